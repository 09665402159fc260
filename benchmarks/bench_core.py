"""Closed-loop free-flight hover (flight software at 50 Hz, logging) against raw ``mj_step`` on the same
compiled model for the same number of physics steps, in one process. Target ratio >= 0.7."""

import time

import mujoco

from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator

DURATION_S = 60.0


def main():
    vehicle = "anteos-p2a2"
    run_scenario("rest", vehicle, scene="free-flight", duration_s=1.0)  # warm-up (imports, caches)
    t0 = time.perf_counter()
    res = run_scenario("rest", vehicle, scene="free-flight", duration_s=DURATION_S)
    closed = time.perf_counter() - t0
    assert res.stopped is None, res.stopped

    sim = Simulator("free-flight", vehicle)
    m, d = sim.model, sim.data
    nstep = int(round(DURATION_S / m.opt.timestep))
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=nstep)
    raw = time.perf_counter() - t0

    print(f"free-flight hover, {DURATION_S:.0f} s, {nstep} physics steps")
    print(f"  closed loop (build + flight software + logging): {closed:.2f} s = {DURATION_S / closed:6.1f}x real time")
    print(f"  raw mj_step on the same model:                   {raw:.2f} s = {DURATION_S / raw:6.1f}x real time")
    print(f"  ratio closed-loop / raw speed: {raw / closed:.2f} (target >= 0.70)")


if __name__ == "__main__":
    main()
