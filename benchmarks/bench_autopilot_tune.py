"""Speed of tuning an autopilot's own loops (rotorlab.tune.autopilot): one start of the three-axis PX4 problem
at 250 Hz on tuhh-quad-like axis models (inertia, the 27 rad/s motor lag, 24-28 ms delays, yaw 6.5 loop periods),
against the generic spec derived from them. Prints wall and CPU time per part (no asserts). Target: one start of
the three-axis problem <= 2 s (issue 28). Run: ``python benchmarks/bench_autopilot_tune.py``.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import tomllib  # noqa: E402

import control as ct  # noqa: E402
from timing import Clock  # noqa: E402

from rotorlab.autopilots import px4  # noqa: E402
from rotorlab.tune.autopilot import axis_plant, px4_autotune_params, tune_autopilot  # noqa: E402
from rotorlab.tune.autopilot_spec import generic_spec  # noqa: E402
from rotorlab.tune.spec import parse_spec  # noqa: E402

DT_S = 1 / 250
MOTOR = 27.0
MODELS = {  # rate per unit normalised torque, delay (s)
    "roll": (ct.tf([107.0], [1 / MOTOR, 1.0, 0.0]), 0.024),
    "pitch": (ct.tf([100.0], [1 / MOTOR, 1.0, 0.0]), 0.028),
    "yaw": (ct.tf([25.0], [1 / MOTOR**2, 2 / MOTOR, 1.0]) * ct.tf([1.0], [1.0, 0.4]), 0.026),
}


def main():
    p = px4.TABLE.defaults()
    with Clock() as cp:
        plants = {a: axis_plant(G, d, DT_S) for a, (G, d) in MODELS.items()}
    with Clock() as ca:
        gains, rejected = px4_autotune_params(plants, p)
    base = {"defaults": p, "px4-autotune": {**p, **gains}}
    with Clock() as cs:
        text = generic_spec(px4, {a: (plants[a], *MODELS[a]) for a in MODELS}, DT_S, p, base)
        spec = parse_spec(tomllib.loads(text))
    with Clock() as ct1:
        res = tune_autopilot(spec, plants, p, starts=1)
    print(f"plants (exact fractional delay)   : {cp}")
    print(f"PX4 autotune baseline (3 axes)    : {ca}  rejected: {sorted(rejected) or 'none'}")
    print(f"generic spec from plant+baselines : {cs}")
    print(f"one start, three-axis PX4 problem : {ct1}  (target <= 2 s)  hard goals pass: "
          f"{all(r.passed for r in res.values())}")
    for a, r in res.items():
        print(f"  {a:5s} {r.time_s:5.2f} s  objective {r.objective:.3f}  "
              + ", ".join(f"{k}={v:.4g}" for k, v in r.gains.items()))


if __name__ == "__main__":
    main()
