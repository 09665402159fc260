"""Scale invariance of the structured H-inf engine: every problem of the project's suite (the families of
benchmarks/hinf_problems.py and the COMPleib problems of benchmarks/compleib.py) solved with the default options
(``hinfstruct(P, K, ny, nu)``: several starts, then basin hopping from the best) as written and with its controls,
then its measurements, in units ``f`` times larger for ``f`` in {1e-3, 1e-2, 0.1, 10, 100, 1e3} (:func:`hinf_problems.rescaled`). The optimum's
gamma does not change with units; the table gives the largest relative deviation of the 12 rescaled runs'
gamma from the unscaled one, how many took the same path (every start's, sweep start's and hop's gamma equal to
the unscaled run's), and the CPU time per run (starts and hops together). The acceptance bar is 0.5 %.
``--starts 1 --hops 0`` measures one plain start instead (the engine's arithmetic alone).

Run: ``python benchmarks/bench_hinf_scaling.py [--problems AC15 chain40] [--jobs 1] [--executor dask://HOST:PORT]``.
The runs go through the project's executor (``--jobs N``: a local pool of N processes, all problems' runs in one
map). The machine may be shared: the load average is printed.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compleib  # noqa: E402
from hinf_problems import PROBLEMS, Problem, rescaled  # noqa: E402

from rotorlab.executor import get_executor  # noqa: E402
from rotorlab.tune.hinfstruct import hinfstruct  # noqa: E402

FACTORS = (1e-3, 1e-2, 0.1, 10.0, 100.0, 1e3)


def suite():
    """Builders of every problem: the project's families and the COMPleib problems."""
    out = dict(PROBLEMS)
    for name, data in compleib.PROBLEMS.items():
        def build(name=name, data=data):
            P, ny, nu = compleib.plant(data)
            return Problem(name, P, ny, nu, "static")
        out[name] = build
    return out


def _solve(job):
    name, side, factor, kw = job
    warnings.simplefilter("ignore")
    prob = suite()[name]()
    if side == "u":
        prob = rescaled(prob, factor, 1.0)
    elif side == "y":
        prob = rescaled(prob, 1.0, factor)
    r = hinfstruct(prob.P, prob.controller, prob.nmeas, prob.ncon, **kw)
    return r.gamma, r.slope, r.total_cpu_s, (r.starts, r.sweep, r.hops)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--problems", nargs="*", default=list(suite()))
    ap.add_argument("--jobs", type=int, default=1, help="processes of the local pool (1: serial)")
    ap.add_argument("--executor", default=None, help="an executor spec instead, e.g. dask://HOST:PORT")
    ap.add_argument("--starts", type=int, default=None, help="starts per run (default: the engine's)")
    ap.add_argument("--factors", type=float, nargs="*", default=list(FACTORS), help="a subset of the scales")
    ap.add_argument("--hops", type=int, default=None, help="basin-hopping runs per round (default: the engine's)")
    a = ap.parse_args()
    kw = {"starts": a.starts, "hops": a.hops}
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    rows = []
    nf = len(a.factors)
    per = 1 + 2 * nf  # runs per problem: unscaled, then each factor on the controls and on the measurements
    # every problem's runs in one map, so a pool of many processes is kept busy across problems
    jobs = [job for name in a.problems
            for job in [(name, None, 1.0, kw)] + [(name, side, f, kw) for side in "uy" for f in a.factors]]
    with get_executor(a.executor or ("local" if a.jobs > 1 else "serial"), a.jobs) as ex:
        results = ex.map(_solve, jobs, desc="runs", progress=True)
    for i, name in enumerate(a.problems):
        res = results[i * per: (i + 1) * per]
        g0 = res[0][0]
        dev = [r[0] / g0 - 1 for r in res[1:]]
        worst = max(dev, key=abs)
        secs = [r[2] for r in res]
        # the same path: every start's, sweep start's and hop's gamma equal to the unscaled run's
        same = sum(r[3] == res[0][3] for r in res[1:])
        rows.append((name, g0, worst, sum(abs(d) <= 5e-3 for d in dev), len(dev), np.median(secs), res[0][1], same))
        print(f"{name}: gamma {g0:.6g} (slope {res[0][1]:.2g}); rescaled u: "
              f"{[f'{r[0]:.6g}' for r in res[1:1 + nf]]}; y: {[f'{r[0]:.6g}' for r in res[1 + nf:]]}; worst "
              f"{worst:+.1e}; same path {same}/{per - 1}; median {np.median(secs):.1f} CPU s/run", flush=True)
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    print(f"\n| problem | gamma (unscaled) | slope | worst deviation, {per - 1} rescaled runs | within 0.5 % "
          "| same path | median CPU s/run |")
    print("|---|---|---|---|---|---|---|")
    for name, g0, worst, ok, n, sec, sl, same in rows:
        print(f"| {name} | {g0:.5g} | {sl:.1e} | {worst:+.1e} | {ok}/{n} | {same}/{n} | {sec:.1f} |")


if __name__ == "__main__":
    main()
