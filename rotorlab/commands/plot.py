"""Plot a run's time histories to a PNG (no display needed).

By default one panel per quantity: the angle with its set-point, the rate with its set-point and the command
of each axis that moved, then position, wind and rope tension where the run logged them; the in-flight gain
switch of a hover run is marked. --signals picks the panels instead (a+b draws two signals in one panel).
"""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("plot", help="plot a run's signals to a PNG", **describe(__doc__))
    p.add_argument("run", help="run folder (rotorlab run --out DIR) or its log.parquet")
    p.add_argument("--signals", default=None, metavar="A,B+C",
                   help="comma list of panels, each a signal or signals joined by + (default: the scenario's)")
    p.add_argument("--out", default=None, help="PNG to write (default RUN/plot.png)")
    return p


def run(args) -> int:
    from rotorlab.plotting import plot_runs, read_run

    try:
        from rotorlab.atomic import check_output

        r = read_run(args.run)
        src = Path(args.run)
        folder = src if src.is_dir() else src.parent
        out = Path(args.out) if args.out else folder / "plot.png"
        check_output(out, [folder / "log.parquet" if src.is_dir() else src, folder / "run.json"])
        signals = [s.strip() for s in args.signals.split(",") if s.strip()] if args.signals else None
        path = plot_runs([r], out, signals)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    print(f"wrote {path}")
    return 0
