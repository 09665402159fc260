"""Structured H-inf engine on the project's hard problem families (benchmarks/hinf_problems.py).

For every problem: ``hinfstruct`` with ``--starts`` starts (seed 0), the best gamma, how many starts end
within 1 % and 2 % of the best known value (ours or the baseline's), the first start's gap to it (the start from
the blocks' values, K = 0 for static gains: what one start with the default options gives), the median time per
start, and two references: the full-order optimum from
``control.hinfsyn`` where the structure is full order, and a long derivative-free baseline (scipy
Nelder-Mead on the exact ab13dd norm, ``--baseline-fev`` evaluations per parameter, started from the engine's
best controller): if it finds a lower gamma the engine stopped short of a local minimum. Prints a Markdown
table (the README's). The machine may be shared: the load average is printed with the times.

Run: ``python benchmarks/bench_hinfstruct.py [--starts 50] [--hops 0] [--sweep off] [--problems chain40 mimo8]``. With
``--hops 0`` (the default here) every start is one plain run, as the start statistics need; the engine's gain-scale
sweep (on the flex20 family only, by default) adds its own starts, listed apart and left out of the start statistics.
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
from rotorlab.executor import get_executor  # noqa: E402
from rotorlab.tune.hinfstruct import closed_loop, hinfstruct  # noqa: E402


def baseline(prob, result, fev_per_param):
    """Nelder-Mead on the exact norm (inf when unstable) from the engine's best controller."""
    S = result.structure
    th0 = np.array(list(result.params.values()))

    def f(th):
        return lti.hinfnorm(closed_loop(prob.P, prob.nmeas, prob.ncon, S.ss(th)))[0]

    r = minimize(f, th0, method="Nelder-Mead",
                 options={"maxfev": fev_per_param * th0.size, "adaptive": True, "xatol": 1e-10, "fatol": 1e-12})
    return min(float(r.fun), f(th0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--starts", type=int, default=10)
    ap.add_argument("--hops", type=int, default=0, help="basin-hopping runs per round after the starts (0: none)")
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS))
    ap.add_argument("--sweep", choices=["auto", "on", "off"], default="auto",
                    help="the engine's gain-scale sweep (auto: where the plant calls for it)")
    ap.add_argument("--baseline-fev", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    rows = []
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    for name in a.problems:
        prob = PROBLEMS[name]()
        t = time.perf_counter()
        with get_executor("local" if a.jobs > 1 else "serial", a.jobs) as ex:
            r = hinfstruct(prob.P, prob.controller, prob.nmeas, prob.ncon, starts=a.starts, hops=a.hops, seed=0,
                           sweep={"auto": None, "on": True, "off": False}[a.sweep], executor=ex)
        wall = time.perf_counter() - t
        g = np.array(r.starts)
        tb = time.perf_counter()
        gb = baseline(prob, r, a.baseline_fev)
        tb = time.perf_counter() - tb
        bound = prob.hinfsyn_bound() if prob.full_order else np.nan
        best = min(r.gamma, gb)
        near1, near = int(np.sum(g <= best * 1.01)), int(np.sum(g <= best * 1.02))
        # a start whose stabilisation phase failed has gamma inf and no time (the call still succeeds)
        row = (name, prob.P.nstates, len(r.params), r.gamma, bound, gb, 100 * (r.gamma / best - 1), near,
               len(g), np.nanmedian(r.start_times_s), np.nanmedian(r.start_cpu_s), tb, near1,
               100 * (g[0] / best - 1), r.slope)
        rows.append(row)
        print(f"{name}: gamma {r.gamma:.6g} (slope {r.slope:.2g})  hinfsyn {bound:.6g}  baseline {gb:.6g}  "
              f"first start {g[0]:.6g}  starts within 1 % / 2 %: {near1}/{near}/{len(g)}  unstabilised starts: "
              f"{int(np.sum(~np.isfinite(g)))}  median s/start "
              f"{row[9]:.2f} wall, {row[10]:.2f} CPU  (all starts {wall:.1f} s, baseline {tb:.1f} s, "
              f"load {os.getloadavg()[0]:.1f})\n  per start: {np.round(g, 6).tolist()}\n  gain-scale sweep's starts: "
              f"{np.round(r.sweep, 6).tolist()}", flush=True)
    print()
    print("| problem | states | params | gamma (ours) | full-order bound | baseline | gap to best | first start's gap "
          "| starts within 1 % / 2 % | median s/start (wall / CPU) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, n, npar, g, bound, gb, gap, near, ns, tps, cps, _, near1, gap0, _ in rows:
        b = f"{bound:.4f} ({100 * (g / bound - 1):+.2f} %)" if np.isfinite(bound) else "-"
        print(f"| {name} | {n} | {npar} | {g:.4f} | {b} | {gb:.4f} | {gap:.2f} % | {gap0:.2f} % | {near1} / {near} of "
              f"{ns} | {tps:.1f} / {cps:.1f} |")


if __name__ == "__main__":
    main()
