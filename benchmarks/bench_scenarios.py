"""Speed of the validation scenarios: real-time factor (simulated s per wall s) of each, its ratio to raw
``mj_step`` of the same compiled model over the same ticks, and the cost of wind and rope over an undisturbed run.

Run: ``python benchmarks/bench_scenarios.py [duration_s]``. Prints measured numbers only (no asserts).
"""

from __future__ import annotations

import sys
import time

import mujoco

from rotorlab.gains import parse_gains
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator

STD = parse_gains({"pitch": {"outer": {"kp": 9.26, "kd": 1.11, "tf": 0.03},
                             "inner": {"kp": 0.257, "ki": 0.643, "kd": 0.0231, "tf": 0.0225}}}, name="standard")
CASES = [  # label, scenario, scene, options
    ("setpoint (undisturbed rig)", "setpoint", "pitch-rig", {}),
    ("gust (wind, rig)", "gust", "pitch-rig", {}),
    ("rope-pull (rope, rig)", "rope-pull", "pitch-rig", {}),
    ("prbs (rig)", "prbs", "pitch-rig", {}),
    ("prbs-closed (rig)", "prbs-closed", "pitch-rig", {}),
    ("hover, still air", "hover", "free-flight", {"wind_mps": 0.0, "turbulence": False, "switch_s": None}),
    ("hover, wind + Dryden", "hover", "free-flight", {"switch_s": None}),
    ("prbs-flight (wind + Dryden)", "prbs-flight", "free-flight", {}),
]


def _best(fn, repeat=3):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def raw_step_s(scene: str, n_ticks: int) -> float:
    sim = Simulator(scene, "anteos-p2a2", sensor_noise=False)
    m, d = sim.model, sim.data

    def go():
        for _ in range(n_ticks):
            mujoco.mj_step(m, d, nstep=sim.n_substeps)

    return _best(go)


def main(duration_s: float = 10.0) -> None:
    n_ticks = int(round(duration_s / 0.02))
    raw = {s: raw_step_s(s, n_ticks) for s in ("pitch-rig", "free-flight")}
    print(f"{duration_s:g} s runs, {n_ticks} ticks of 20 physics steps; best of 3")
    print(f"raw mj_step: pitch-rig {duration_s / raw['pitch-rig']:.1f}x real time, "
          f"free-flight {duration_s / raw['free-flight']:.1f}x real time")
    wall = {}
    for label, name, scene, opts in CASES:
        wall[label] = _best(lambda name=name, scene=scene, opts=opts: run_scenario(
            name, "anteos-p2a2", scene=scene, gains=STD, duration_s=duration_s, options=opts))
        print(f"{label:32s} {duration_s / wall[label]:6.1f}x real time, {wall[label] / raw[scene]:5.2f}x raw mj_step")
    base_rig, base_ff = wall["setpoint (undisturbed rig)"], wall["hover, still air"]
    print(f"wind on the rig:  {100 * (wall['gust (wind, rig)'] / base_rig - 1):+.1f} % over the undisturbed run")
    print(f"rope on the rig:  {100 * (wall['rope-pull (rope, rig)'] / base_rig - 1):+.1f} % over the undisturbed run")
    print(f"wind + Dryden in flight: {100 * (wall['hover, wind + Dryden'] / base_ff - 1):+.1f} % over still air")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 10.0)
