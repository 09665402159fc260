"""Speed of the structured H-inf tuner (prints times and objectives; no asserts).

1. P2-A2 cascade on the test-bed model (7 parameters, discrete 50 Hz, 3-sample delay, shipped spec):
   one start, 20 starts on 2 processes, and scipy Nelder-Mead on the same objective (max soft goal,
   hard goals as an exact penalty) from the same start.
2. Static output feedback (2x2) on a random stable 40-state plant, one start.
Run: ``python benchmarks/bench_tune.py``.
"""

import time

import control as ct
import numpy as np
from scipy.optimize import minimize

from rotorlab.gains import load_gains
from rotorlab.tune.cascade import cascade_structure, gains_to_theta, plant_model, theta_to_gains
from rotorlab.tune.goals import evaluate, objective, tune_cascade
from rotorlab.tune.hinfstruct import hinfstruct
from rotorlab.tune.spec import load_spec


def cascade():
    spec = load_spec("anteos-p2a2")
    model = plant_model([12.517, 12.517 * 2.906], [1, 5.583, 21.3], 0.06, "test-bed")
    std = load_gains("vehicles/anteos-p2a2/gains/standard.toml")
    t0 = time.perf_counter()
    r1 = tune_cascade(spec, [model], std)
    t1 = time.perf_counter() - t0
    print(f"cascade, 1 start     : {t1:6.2f} s  objective {r1.objective:.4f}  "
          f"hard goals pass: {all(r.passed for r in r1.report if r.hard)}")
    t0 = time.perf_counter()
    r20 = tune_cascade(spec, [model], std, starts=20, seed=0, n_jobs=2)
    t20 = time.perf_counter() - t0
    print(f"cascade, 20 starts/2p: {t20:6.2f} s  objective {r20.objective:.4f}  "
          f"(per-start objectives min/median {np.nanmin(r20.starts):.4f}/{np.median(r20.starts):.4f})")

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

    t0 = time.perf_counter()
    nm = minimize(f, np.zeros(free.sum()), method="Nelder-Mead", options={"maxfev": 600, "xatol": 1e-4,
                                                                         "fatol": 1e-6})
    tn = time.perf_counter() - t0
    print(f"Nelder-Mead (600 ev) : {tn:6.2f} s  objective {nm.fun:.4f}  ({nm.nfev} evaluations)")


def sof40():
    rng = np.random.default_rng(0)
    G = ct.rss(40, 4, 4, strictly_proper=True)
    A = np.asarray(G.A) - (max(0.0, np.max(np.linalg.eigvals(G.A).real)) + 0.1) * np.eye(40)
    P = ct.ss(A, G.B, G.C, np.zeros((4, 4)))
    t0 = time.perf_counter()
    r = hinfstruct(P, "static", 2, 2, starts=1, seed=rng.integers(1 << 30))
    print(f"SOF 2x2, 40 states   : {time.perf_counter() - t0:6.2f} s  gamma {r.gamma:.4f} "
          f"(K = 0 gives {hinfstruct_zero(P):.4f})")


def hinfstruct_zero(P):
    from rotorlab import lti

    return lti.hinfnorm(P[:2, :2])[0]


if __name__ == "__main__":
    cascade()
    sof40()
