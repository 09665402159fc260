"""Per-tick cost of a headless closed-loop run, as two ratios measured in one process over interleaved repeats of
the process's CPU time (``time.process_time``: the shared machine's load does not count, and what is left of it
cancels in the ratios):

1. closed-loop speed / raw ``mj_step`` speed: ``run_scenario('rest', scene='free-flight')`` (build, flight software
   at 50 Hz, IMU sampling, logging, metrics) against ``mj_step`` on the same compiled model, from the same reset
   state (the hover keyframe), for the same number of physics steps (target >= 0.80);
2. wind cost: ``hover`` (mean wind plus Dryden turbulence, no gain switch) over ``rest`` in free flight, both in
   position hold with the same duration (target <= +20 %).

Each ratio is the median over the repeats of the ratio of two runs taken back to back, not the ratio of medians
taken at different moments: on the shared 2-core machine the same 30,000 raw steps take 0.55 to 0.99 s CPU within
one process (other processes' cache and memory traffic). The two runs of each target ratio are neighbours in every
repeat (raw beside rest, rest beside wind) and the order alternates (raw without sensors, raw, rest, wind, then
wind, rest, raw, raw without sensors) so that a drift within a repeat favours neither side. The noise left is
mostly from run to run, not a slow drift (lag-1 correlation of successive runs about 0.2, of a raw run and its
neighbouring closed-loop run 0.6; 40 alternating pairs), so only more pairs narrow the median: single ratios range
about 0.6-1.2 on this machine, and 21 repeats (about 80 s) put the median's 5-95 % range within about
-0.03/+0.03 where 11 gave -0.03/+0.06 (a bootstrap of those 40 pairs). Runs of 15 s instead of 30 s would give
more pairs for the time but weigh the fixed cost of a run, the model build, twice as much.

For reading the first ratio: the simulator has MuJoCo skip the sensors in the physics steps between ticks (they
are read at the tick only; :meth:`rotorlab.sim.simulator.Simulator.tick`), which raw ``mj_step`` of the model
computes in every step, and in this run, where nothing reads the accelerometer, it skips the acceleration pass at
the tick too (``Simulator.forces_at_tick``). The script prints the raw speed with the sensors off too, the physics
the closed loop actually runs, and the closed loop's speed against it.
"""

import statistics
import time

from timing import raw_step_s
from tqdm import tqdm

from rotorlab.sim.runner import run_scenario

VEHICLE = "anteos-p2a2"
DURATION_S = 30.0
REPEATS = 21


def _closed(name: str, **options) -> float:
    t0 = time.process_time()
    res = run_scenario(name, VEHICLE, scene="free-flight", duration_s=DURATION_S, options=options)
    dt = time.process_time() - t0
    assert res.stopped is None, res.stopped
    return dt


def _raw(sensors: bool = True) -> float:
    return raw_step_s(VEHICLE, DURATION_S, sensors)


# in run order: each target ratio's two runs are neighbours (main)
RUNS = {
    "raw_nosensor": lambda: _raw(sensors=False),
    "raw": _raw,
    "rest": lambda: _closed("rest"),
    "wind": lambda: _closed("hover", switch_s=None),
}


def main():
    for run in RUNS.values():  # warm-up: imports, caches
        run()
    sec = {k: [] for k in RUNS}
    order = list(RUNS)
    for _ in tqdm(range(REPEATS), desc="repeats", leave=False):
        for k in order:
            sec[k].append(RUNS[k]())
        order.reverse()

    def ratios(num, den, offset=0.0):
        r = [a / b - offset for a, b in zip(sec[num], sec[den])]
        return statistics.median(r), min(r), max(r)

    speed = ratios("raw", "rest")
    physics = ratios("raw_nosensor", "rest")
    wind = ratios("wind", "rest", 1.0)
    print(f"free flight, {DURATION_S:.0f} s simulated, {REPEATS} interleaved repeats (CPU s: median, min-max)")
    for k, what in (("raw", "raw mj_step (same model, same physics steps)"),
                    ("raw_nosensor", "raw mj_step, sensors off (the closed loop's physics)"),
                    ("rest", "closed loop 'rest' (build + flight software + IMU + log)"),
                    ("wind", "closed loop 'hover' (+ mean wind + Dryden)")):
        s = statistics.median(sec[k])
        print(f"  {what:57s} {s:.3f} s ({min(sec[k]):.3f}-{max(sec[k]):.3f}) = {DURATION_S / s:5.1f}x real time")
    print(f"  ratio closed-loop / raw speed: {speed[0]:.2f} (repeats {speed[1]:.2f}-{speed[2]:.2f}; target >= 0.80)")
    print(f"  ratio closed-loop / raw speed with sensors off: {physics[0]:.2f} "
          f"(repeats {physics[1]:.2f}-{physics[2]:.2f}; for reading, no target)")
    print(f"  wind + Dryden cost over the undisturbed run: {wind[0]:+.0%} "
          f"(repeats {wind[1]:+.0%} to {wind[2]:+.0%}; target <= +20 %)")


if __name__ == "__main__":
    main()
