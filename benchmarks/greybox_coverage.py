"""Coverage of the grey-box intervals over seeds (issue 13): ref. 002's closed-loop identification of each TUHH
axis (:func:`rotorlab.greybox_axes.identify_axis`, the pipeline's settings: ten periods averaged, one restart)
repeated over seeds; per parameter, how often the 95 % period-to-period interval holds the structure's
pseudo-true value (:func:`rotorlab.greybox_axes.truth`), the spread of the estimates between seeds against the
standard error the intervals report, and the estimates' error to the twin's own parameters
(:func:`rotorlab.greybox_axes.physical`). Not a test: 3 axes x 10 seeds take about 4 min on 2 processes.

    python benchmarks/greybox_coverage.py --seeds 10 --jobs 2
"""

from __future__ import annotations

import argparse

import numpy as np

from rotorlab.executor import LocalExecutor
from rotorlab.greybox_axes import AXES, identify_axis


def one(task):
    axis, seed = task
    return identify_axis("tuhh-quad", axis, seed=seed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--axes", default=",".join(AXES))
    a = ap.parse_args()
    axes = a.axes.split(",")
    tasks = [(ax, s) for ax in axes for s in range(a.seeds)]
    out = LocalExecutor(a.jobs).map(one, tasks, desc="axes x seeds", progress=True)
    print(f"{'axis':5s} {'par':3s} {'inside':>7s} {'mean':>10s} {'sd(seeds)':>10s} {'sd(CI)':>10s} "
          f"{'truth':>10s} {'physical':>10s} {'err phys':>9s}")
    for ax in axes:
        rs = [r for (axis, _), r in zip(tasks, out) if axis == ax and "params" in r]
        stopped = sum(1 for (axis, _), r in zip(tasks, out) if axis == ax and "params" not in r)
        for k in rs[0]["params"]:
            v = np.array([r["params"][k] for r in rs])
            inside = sum(r["inside"][k] for r in rs)
            tr, ph = rs[0]["truth"][k], rs[0]["physical"][k]
            print(f"{ax:5s} {k:3s} {inside:>3d}/{len(rs):<3d} {v.mean():10.5g} {v.std(ddof=1):10.3g} "
                  f"{np.mean([r['std'][k] for r in rs]):10.3g} {tr:10.5g} {ph:10.5g} "
                  f"{100 * (v.mean() / ph - 1):+8.2f}%" + (f"  ({stopped} runs stopped)" if stopped else ""))


if __name__ == "__main__":
    main()
