"""Compare runs: their key metrics side by side (with units) and their time histories overlaid in a PNG.

The runs are run folders (rotorlab run --out DIR), typically one scenario with different gain sets, e.g.
rotorlab run setpoint --gains standard --out a; rotorlab run setpoint --gains optimal-testbed --out b;
rotorlab compare a b. The last column is the change of the last run against the first, in %.
"""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("compare", help="compare runs: metrics table and overlaid signals (PNG)", **describe(__doc__))
    p.add_argument("runs", nargs="+", metavar="RUN", help="two or more run folders")
    p.add_argument("--signals", default=None, metavar="A,B+C",
                   help="comma list of panels, each a signal or signals joined by + (default: the scenario's)")
    p.add_argument("--out", default="compare.png", help="PNG to write")
    p.add_argument("--all-metrics", action="store_true", help="every metric, not only the scenario's key ones")
    return p


def table_lines(runs, all_metrics: bool = False) -> list[str]:
    """The metrics of ``runs`` side by side: key metrics first, unit in the label, change last vs first in %."""
    from rotorlab.keymetrics import flatten_metrics, fmt, key_rows

    scen = runs[0]["info"].get("scenario", "")
    flats = [flatten_metrics(r["info"].get("metrics", {})) for r in runs]
    rows = key_rows(scen, flats, rest=all_metrics)
    names = [r["label"] for r in runs]
    labels = [f"{lab} [{unit}]" if unit else lab for _, lab, unit, _ in rows]
    w = max([len(x) for x in labels] + [6])
    cw = max([len(n) for n in names] + [9])
    L = [f"{'metric':<{w}}  " + "  ".join(f"{n:>{cw}}" for n in names) + f"  {'change':>9}"]
    for lab, (_, _, _, vals) in zip(labels, rows):
        a, b = vals[0], vals[-1]
        chg = f"{100 * (b - a) / abs(a):+.1f} %" if a not in (None, 0) and b is not None else "-"
        L.append(f"{lab:<{w}}  " + "  ".join(f"{fmt(v):>{cw}}" for v in vals) + f"  {chg:>9}")
    return L


def run(args) -> int:
    from rotorlab.plotting import plot_runs, read_run

    if len(args.runs) < 2:
        raise CLIError("compare needs at least two run folders")
    try:
        from rotorlab.atomic import check_output

        runs = [read_run(p) for p in args.runs]
        check_output(args.out, [f for p in map(Path, args.runs) for f in
                                ((p / "log.parquet", p / "run.json") if p.is_dir() else (p, p.parent / "run.json"))])
        scen = {r["info"].get("scenario") for r in runs}
        if len(scen) > 1:
            raise CLIError(f"the runs are of different scenarios ({', '.join(sorted(map(str, scen)))}); compare runs "
                           "of one scenario")
        for r, p in zip(runs, args.runs):
            g = r["info"].get("gains")
            r["label"] = f"{Path(p).name}" + (f" ({g})" if g and g not in Path(p).name else "")
        signals = [s.strip() for s in args.signals.split(",") if s.strip()] if args.signals else None
        info = runs[0]["info"]
        path = plot_runs(runs, args.out, signals, title=f"{info.get('scenario', '')} on {info.get('vehicle', '')}: "
                                                        + " vs ".join(r["label"] for r in runs))
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    print("\n".join(table_lines(runs, args.all_metrics)))
    print(f"wrote {path}")
    return 0
