"""Speed of the twin flying an autopilot's own laws (``--controller px4:defaults`` / ``ardupilot:defaults``) at the
vehicle's loop rate, as ratios to raw ``mj_step`` of the same model, measured in one process over interleaved
repeats of the process's CPU time (``time.process_time``), as bench_core.py does:

    speed ratio = CPU time of raw mj_step for the run's physics steps / CPU time of the closed-loop run

for ``run_scenario('rest', 'tuhh-quad', scene='free-flight')`` (position hold, 250 Hz flight software: 4 physics
steps a tick) with the built-in cascade, with PX4's laws and with ArduPilot's. Each ratio is the median over the
repeats of the ratio of two neighbouring runs (raw beside each closed loop, the order alternating), so the load of
the shared machine cancels. Target of issue 28: PX4's laws at >= 0.6x raw mj_step.

Usage: ``python benchmarks/bench_autopilots.py [repeats]``
"""

import statistics
import sys
import time

import mujoco

from rotorlab.sim.control.autopilot import AutopilotSpec
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator

VEHICLE = "tuhh-quad"
DURATION_S = 10.0


def _closed(controller) -> float:
    t0 = time.process_time()
    res = run_scenario("rest", VEHICLE, scene="free-flight", duration_s=DURATION_S, controller=controller)
    dt = time.process_time() - t0
    assert res.stopped is None, res.stopped
    return dt


def _raw() -> float:
    sim = Simulator("free-flight", VEHICLE, sensor_noise=False)
    m, d = sim.model, sim.data
    nstep = int(round(DURATION_S / m.opt.timestep))
    t0 = time.process_time()
    mujoco.mj_step(m, d, nstep=nstep)
    return time.process_time() - t0


def main(repeats: int = 11) -> dict:
    flown = {"cascade": None, "px4": AutopilotSpec.from_params("px4"),
             "ardupilot": AutopilotSpec.from_params("ardupilot")}
    ratios = {k: [] for k in flown}
    for i in range(repeats):
        order = list(flown) if i % 2 == 0 else list(reversed(flown))
        for name in order:
            if i % 2 == 0:
                raw = _raw()
                closed = _closed(flown[name])
            else:
                closed = _closed(flown[name])
                raw = _raw()
            ratios[name].append(raw / closed)
    out = {k: statistics.median(v) for k, v in ratios.items()}
    for k, v in ratios.items():
        print(f"{k:>10}: speed {out[k]:.3f}x raw mj_step (range {min(v):.3f}-{max(v):.3f}, {len(v)} pairs)")
    return out


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 11)
