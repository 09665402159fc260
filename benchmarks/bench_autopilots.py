"""Speed of the twin flying an autopilot's own laws (``--controller px4:defaults`` / ``ardupilot:defaults``) at the
vehicle's loop rate, as ratios to raw ``mj_step`` of the same model, measured in one process over interleaved
repeats of the process's CPU time (``time.process_time``), as bench_core.py does:

    speed ratio = CPU time of raw mj_step for the run's physics steps / CPU time of the closed-loop run

for ``run_scenario('rest', VEHICLE, scene='free-flight')`` (position hold, the vehicle's 250 Hz flight software:
4 physics steps a tick) with the built-in cascade, with PX4's laws and with ArduPilot's, and, for reference, the
50 Hz cascade of ``anteos-p2a2`` (20 physics steps a tick) against raw ``mj_step`` of its own model. Each ratio is
the median over the repeats of the ratio of two neighbouring runs (a raw run beside each closed loop, the order
alternating), so the load of the shared machine cancels; the spread printed is the range and the 25-75 %
quantiles of those ratios. Runs of 30 s, as bench_core.py's: the fixed cost of a run (model build, metrics) weighs
a third of what it would in 10 s.

The per-tick cost printed beside each ratio is the closed loop's CPU time less that of the raw steps with the
sensors off (the physics the closed loop runs; the raw neighbour scaled by the median ratio of the two raw kinds),
per control tick: what the runner, the sensors, the flight software and the log cost a tick, the number that
decides how the speed falls with the loop rate (issue 28: "eight times the controller ticks must not cost eight
times the time"). Target of issue 28: PX4's laws at >= 0.6x raw mj_step.

The modules of one tick run compiled where the install compiled them (:mod:`rotorlab.compiled`; the first line
printed says how many); ``ROTORLAB_PURE_PYTHON=1 python benchmarks/bench_autopilots.py`` measures the Python build.

Usage: ``python benchmarks/bench_autopilots.py [repeats]``
"""

import os
import statistics
import sys
import time

from timing import raw_step_s

from rotorlab import compiled
from rotorlab.sim.control.autopilot import AutopilotSpec
from rotorlab.sim.runner import run_scenario

VEHICLE = "tuhh-quad"
REFERENCE_VEHICLE = "anteos-p2a2"  # the 50 Hz cascade of the "0.8x today"
DURATION_S = 30.0
TARGET = 0.6


def _closed(vehicle: str, controller) -> tuple[float, int]:
    t0 = time.process_time()
    res = run_scenario("rest", vehicle, scene="free-flight", duration_s=DURATION_S, controller=controller)
    dt = time.process_time() - t0
    assert res.stopped is None, res.stopped
    return dt, res.log.n


def _raw(vehicle: str, sensors: bool = True) -> float:
    return raw_step_s(vehicle, DURATION_S, sensors)


#: name -> (vehicle, controller, what)
FLOWN = {
    "cascade": (VEHICLE, None, f"{VEHICLE} built-in cascade, 250 Hz"),
    "px4": (VEHICLE, AutopilotSpec.from_params("px4"), f"{VEHICLE} PX4 laws (px4:defaults), 250 Hz"),
    "ardupilot": (VEHICLE, AutopilotSpec.from_params("ardupilot"),
                  f"{VEHICLE} ArduPilot laws (ardupilot:defaults), 250 Hz"),
    "cascade-50": (REFERENCE_VEHICLE, None, f"{REFERENCE_VEHICLE} built-in cascade, 50 Hz (reference)"),
}


def _quartiles(v):
    q = statistics.quantiles(v, n=4) if len(v) > 1 else [v[0]] * 3
    return q[0], q[2]


def main(repeats: int = 21) -> dict:
    build = compiled.status()
    n_compiled = sum(v == "compiled" for v in build.values())
    print(f"modules of the tick compiled: {n_compiled} of {len(build)} "
          f"({', '.join(sorted(set(build.values())))}); load average {os.getloadavg()[0]:.2f}")
    for vehicle, controller, _ in FLOWN.values():  # warm-up: imports, caches, compiled models
        _closed(vehicle, controller)
        _raw(vehicle)
    ratios = {k: [] for k in FLOWN}
    tick_us = {k: [] for k in FLOWN}
    nosensor = {v: [] for v in {f[0] for f in FLOWN.values()}}  # raw without / with sensors, per vehicle
    for i in range(repeats):
        order = list(FLOWN) if i % 2 == 0 else list(reversed(FLOWN))
        for name in order:
            vehicle, controller, _ = FLOWN[name]
            if i % 2 == 0:
                raw = _raw(vehicle)
                closed, ticks = _closed(vehicle, controller)
            else:
                closed, ticks = _closed(vehicle, controller)
                raw = _raw(vehicle)
            ratios[name].append(raw / closed)
            tick_us[name].append((closed, raw, ticks))
        for vehicle in nosensor:
            a, b = _raw(vehicle, sensors=False), _raw(vehicle)
            nosensor[vehicle].append(a / b)
    physics = {v: statistics.median(r) for v, r in nosensor.items()}
    out = {}
    print(f"free flight 'rest', {DURATION_S:.0f} s simulated, {repeats} interleaved repeats, CPU time; "
          f"speed = raw mj_step of the same model / closed loop (median, 25-75 %, min-max of the pairs)")
    for name, (vehicle, _, what) in FLOWN.items():
        r = ratios[name]
        med, (q1, q3) = statistics.median(r), _quartiles(r)
        per_tick = statistics.median((c - raw * physics[vehicle]) / n * 1e6 for c, raw, n in tick_us[name])
        out[name] = {"speed": med, "tick_us": per_tick}
        target = f" (target >= {TARGET})" if name == "px4" else ""
        print(f"  {what:54s} speed {med:.3f}x ({q1:.3f}-{q3:.3f}, {min(r):.3f}-{max(r):.3f}){target}; "
              f"beyond the physics {per_tick:5.1f} us a tick")
    for v, f in physics.items():
        print(f"  raw mj_step of {v} with the sensors off / with them: {f:.3f} (median)")
    print(f"load average {os.getloadavg()[0]:.2f}")
    return out


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 21)
