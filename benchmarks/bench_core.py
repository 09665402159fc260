"""Per-tick cost of a headless closed-loop run, as two ratios measured in one process with interleaved repeats
(medians) of the process's CPU time (``time.process_time``: the shared machine's load does not count, and what is
left of it cancels in the ratios):

1. closed-loop speed / raw ``mj_step`` speed: ``run_scenario('rest', scene='free-flight')`` (build, flight software
   at 50 Hz, IMU sampling, logging, metrics) against ``mj_step`` on the same compiled model for the same number of
   physics steps (target >= 0.80);
2. wind cost: ``hover`` (mean wind plus Dryden turbulence, no gain switch) over ``rest`` in free flight, both in
   position hold with the same duration (target <= +20 %).
"""

import statistics
import time

import mujoco

from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator

VEHICLE = "anteos-p2a2"
DURATION_S = 30.0
REPEATS = 5


def _closed(name: str, **options) -> float:
    t0 = time.process_time()
    res = run_scenario(name, VEHICLE, scene="free-flight", duration_s=DURATION_S, options=options)
    dt = time.process_time() - t0
    assert res.stopped is None, res.stopped
    return dt


def _raw() -> float:
    sim = Simulator("free-flight", VEHICLE, sensor_noise=False)
    m, d = sim.model, sim.data
    nstep = int(round(DURATION_S / m.opt.timestep))
    t0 = time.process_time()
    mujoco.mj_step(m, d, nstep=nstep)
    dt = time.process_time() - t0
    # held at the hover trim it stays airborne: no contacts that would make the raw steps dearer
    assert d.qpos[2] > 1.0, f"the raw run reached the floor (z = {d.qpos[2]:.2f} m)"
    return dt


def main():
    _closed("rest")  # warm-up: imports, caches
    _closed("hover", switch_s=None)
    raw, rest, wind = [], [], []
    for _ in range(REPEATS):
        raw.append(_raw())
        rest.append(_closed("rest"))
        wind.append(_closed("hover", switch_s=None))
    raw_s, rest_s, wind_s = (statistics.median(x) for x in (raw, rest, wind))
    speed = raw_s / rest_s
    wind_cost = wind_s / rest_s - 1.0
    print(f"free flight, {DURATION_S:.0f} s simulated, medians of {REPEATS} interleaved repeats")
    for what, sec in (("raw mj_step (same model, same physics steps)", raw_s),
                      ("closed loop 'rest' (build + flight software + IMU + log)", rest_s),
                      ("closed loop 'hover' (+ mean wind + Dryden)", wind_s)):
        print(f"  {what:57s} {sec:.3f} s CPU = {DURATION_S / sec:6.1f}x real time")
    print(f"  ratio closed-loop / raw speed: {speed:.2f} (target >= 0.80)")
    print(f"  wind + Dryden cost over the undisturbed run: {wind_cost:+.0%} (target <= +20 %)")


if __name__ == "__main__":
    main()
