"""Reference values of the flexible-structure family (benchmarks/hinf_problems.py, ``flex20s0..2``) by a sweep in
gain scale, independent of hinfstruct's starts.

The optimum of these problems is a nearly rank-one static gain of 1e4-1e5 N per unit displacement that stabilises
only in a thin band of gain scale (on flex20s0 the best controller known is unstable at half and at twice its
largest singular value), which random starts rarely hit. The sweep: for every gain scale ``|K|_F`` on a log grid,
the rank-one gains ``s u v'`` on a grid of the two angles of ``u`` and ``v`` (both signs) are evaluated exactly
(ab13dd), and Nelder-Mead on the sphere ``|K|_F = s`` refines the three best; the hybrid optimiser of
:func:`rotorlab.tune.hinfstruct.hinfstruct` (one start, no hops, not its own gain-scale sweep, a long iteration
budget) then polishes the ``--polish`` best scales' minimisers. 2x2 static output feedback only (the grid is over the two angles).

Run: ``python benchmarks/flex_reference.py [--problems flex20s0] [--angles 24] [--max-iter 2000]``. The machine may
be shared: the load average is printed with the times.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import minimize  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hinf_problems import PROBLEMS  # noqa: E402

from rotorlab import lti  # noqa: E402
from rotorlab.tune.blocks import StaticGain  # noqa: E402
from rotorlab.tune.hinfstruct import closed_loop, hinfstruct  # noqa: E402


def gamma_of(prob, K):
    """Exact closed-loop H-inf norm of the static gain K (inf when the closed loop is unstable)."""
    import control as ct
    cl = closed_loop(prob.P, prob.nmeas, prob.ncon, ct.ss([], [], [], K))
    if np.max(np.linalg.eigvals(np.asarray(cl.A, float)).real) >= 0:
        return np.inf
    return lti.hinfnorm(cl)[0]


def best_at_scale(prob, s, n_angles, nm_fev):
    """Lowest gamma found on the sphere ``|K|_F = s``: rank-one angle grid, then Nelder-Mead from its three best."""
    ang = np.linspace(0.0, np.pi, n_angles, endpoint=False)
    cands = []
    for a in ang:
        for b in ang:
            M = np.outer([np.cos(a), np.sin(a)], [np.cos(b), np.sin(b)])
            for sg in (1.0, -1.0):
                cands.append((gamma_of(prob, sg * s * M), (sg * M).ravel()))
    cands.sort(key=lambda c: c[0])
    best = (np.inf, None)
    for g0, m in cands[:3]:
        if not np.isfinite(g0):
            continue
        r = minimize(lambda m: gamma_of(prob, s * (m / np.linalg.norm(m)).reshape(2, 2)), m, method="Nelder-Mead",
                     options={"maxfev": nm_fev, "xatol": 1e-7, "fatol": 1e-3})
        if r.fun < best[0]:
            best = (float(r.fun), s * (r.x / np.linalg.norm(r.x)).reshape(2, 2))
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--problems", nargs="*", default=["flex20s0", "flex20s1", "flex20s2"])
    ap.add_argument("--scales", type=float, nargs=3, default=[3.0, 6.0, 13], metavar=("LOG10_LO", "LOG10_HI", "N"))
    ap.add_argument("--angles", type=int, default=24)
    ap.add_argument("--nm-fev", type=int, default=600)
    ap.add_argument("--polish", type=int, default=3)
    ap.add_argument("--max-iter", type=int, default=2000)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    rows = []
    for name in a.problems:
        prob = PROBLEMS[name]()
        if prob.controller != "static" or (prob.nmeas, prob.ncon) != (2, 2):
            raise SystemExit(f"{name}: the sweep is for 2x2 static output feedback")
        t = time.perf_counter()
        sweep = []
        for s in np.logspace(a.scales[0], a.scales[1], int(a.scales[2])):
            g, K = best_at_scale(prob, s, a.angles, a.nm_fev)
            sweep.append((g, s, K))
            print(f"{name} |K|_F = {s:.4g}: {g:.6g}", flush=True)
        ts = time.perf_counter() - t
        best = (np.inf, None)
        for g, s, K in sorted(sweep, key=lambda e: e[0])[: a.polish]:
            if not np.isfinite(g):
                continue
            r = hinfstruct(prob.P, StaticGain(2, 2, value=K), 2, 2, starts=1, hops=0, sweep=False,
                           max_iter=a.max_iter)
            Kp = np.array(list(r.params.values())).reshape(2, 2)
            print(f"{name}: polished from |K|_F = {s:.4g} ({g:.6g}): {r.gamma:.8g}, K = {np.round(Kp, 3).tolist()}, "
                  f"slope {r.slope:.2g}", flush=True)
            if r.gamma < best[0]:
                best = (r.gamma, Kp)
        rows.append((name, best[0], best[1], ts, time.perf_counter() - t))
    print("\n| problem | reference gamma | K | singular values of K | sweep s | total s |\n|---|---|---|---|---|---|")
    for name, g, K, ts, tt in rows:
        print(f"| {name} | {g:.6g} | {np.round(K, 1).tolist()} | "
              f"{np.round(np.linalg.svd(K, compute_uv=False), 1).tolist()} | {ts:.0f} | {tt:.0f} |")


if __name__ == "__main__":
    main()
