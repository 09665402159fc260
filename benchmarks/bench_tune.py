"""Speed of the structured H-inf tuner (prints times and objectives; no asserts).

1. P2-A2 cascade on the test-bed model (7 parameters, discrete 50 Hz, 3-sample delay, shipped spec):
   one start, 20 starts on 2 processes, and scipy Nelder-Mead on the same objective (max soft goal,
   hard goals as an exact penalty) from the same start.
2. Static output feedback (2x2) on a random stable 40-state plant, one start.
Every line prints wall time and CPU time (this process plus its finished worker processes), since the
machine may be shared. Targets: one start < 1 s, 20 starts < 10 s on 2 cores (idle machine).
Run: ``python benchmarks/bench_tune.py``.
"""

import os

# one BLAS thread per process: the tuner's matrices are tiny and the multi-start runs one process per core
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


import control as ct  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import minimize  # noqa: E402
from timing import Clock  # noqa: E402

from rotorlab import lti
from rotorlab.gains import load_gains  # noqa: E402
from rotorlab.tune.cascade import cascade_structure, gains_to_theta, plant_model, theta_to_gains  # noqa: E402
from rotorlab.tune.goals import evaluate, objective, tune_cascade  # noqa: E402
from rotorlab.tune.hinfstruct import hinfstruct  # noqa: E402
from rotorlab.tune.spec import load_spec  # noqa: E402
from rotorlab.vehicles import load_vehicle  # noqa: E402


def cascade():
    spec = load_spec("anteos-p2a2")
    pm = load_vehicle("anteos-p2a2").published["testbed"]
    model = plant_model(pm.num, pm.den, pm.delay_s, "test-bed")
    std = load_gains("vehicles/anteos-p2a2/gains/standard.toml")
    with Clock() as c1:
        r1 = tune_cascade(spec, [model], std)
    print(f"P2-A2 cascade, 1 start     : {c1}  objective {r1.objective:.4f}  "
          f"hard goals pass: {all(r.passed for r in r1.report if r.hard)}")
    with Clock() as c20:
        r20 = tune_cascade(spec, [model], std, starts=20, seed=0, n_jobs=2)
    print(f"P2-A2 cascade, 20 starts/2p: {c20}  objective {r20.objective:.4f}  "
          f"(per-start objectives min/median {np.nanmin(r20.starts):.4f}/{np.median(r20.starts):.4f})")
    spec_a2 = load_spec("anteos-a2minib")
    pm = load_vehicle("anteos-a2minib").published["testbed"]
    model_a2 = plant_model(pm.num, pm.den, pm.delay_s, "test-bed")
    with Clock() as ca:
        ra = tune_cascade(spec_a2, [model_a2], load_gains("vehicles/anteos-a2minib/gains/standard.toml"))
    print(f"A2-MINI/B cascade, 1 start : {ca}  objective {ra.objective:.4f}  "
          f"hard goals pass: {all(r.passed for r in ra.report if r.hard)}")

    S = cascade_structure(spec.dt, std["pitch"])
    th0 = gains_to_theta(S, std["pitch"])
    free = np.array([n in spec.tune for n in S.names])

    def f(x):
        th = th0.copy()
        th[free] = th0[free] * np.exp(x)  # log-parametrised so gains keep their sign
        rep = evaluate(spec, theta_to_gains(S, th), [model])
        if not np.all(np.isfinite([r.value for r in rep])):
            return 1e6
        return objective(rep) + 10 * sum(max(0.0, r.value - 1) for r in rep if r.hard)

    with Clock() as cn:
        nm = minimize(f, np.zeros(free.sum()), method="Nelder-Mead", options={"maxfev": 600, "xatol": 1e-4,
                                                                             "fatol": 1e-6})
    print(f"Nelder-Mead (600 ev)       : {cn}  objective {nm.fun:.4f}  ({nm.nfev} evaluations)")


def sof40():
    rng = np.random.default_rng(0)
    # python-control's rss draws from numpy's global generator and takes no seed: seeded here so that the
    # plant, and so the numbers printed, are the same on every run
    np.random.seed(0)
    G = ct.rss(40, 4, 4, strictly_proper=True)
    A = np.asarray(G.A) - (max(0.0, np.max(np.linalg.eigvals(G.A).real)) + 0.1) * np.eye(40)
    P = ct.ss(A, G.B, G.C, np.zeros((4, 4)))
    with Clock() as c:
        r = hinfstruct(P, "static", 2, 2, starts=1, seed=rng.integers(1 << 30))
    print(f"SOF 2x2, 40 states         : {c}  gamma {r.gamma:.4f} (K = 0 gives {hinfstruct_zero(P):.4f})")


def hinfstruct_zero(P):
    return lti.hinfnorm(P[:2, :2])[0]


if __name__ == "__main__":
    cascade()
    sof40()
