"""Run the end-to-end job on a vehicle's twin: experiments -> identification -> bootstrap -> tuning ->
re-injection -> report. With --log FLIGHT.ulg|FLIGHT.bin, start from a real flight instead: identify its three
axes -> calibrate a twin to them -> tune the autopilot's own controller -> fly the log's parameters and the tuned
set in the twin -> report and the parameter file.

Writes OUT/report/report.md and report.html (tables and figures), summary.json (every number), the models,
the gain sets and rerun recordings of the validation runs (open them with rotorlab view OUT); with --log,
OUT/report/report.md (what a pilot needs first), summary.json, tuned.params or tuned.parm and the calibrated
vehicle.toml. Every stage is written atomically and skipped when its inputs are unchanged, so an interrupted
run resumes where it stopped.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rotorlab.cli import CLIError, bounded_int, describe, process_count, seed_int
from rotorlab.errors import RotorlabError

#: most bootstrap replications or Monte Carlo samples (each sample is kept for the statistics)
MAX_SAMPLES = 100_000

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("pipeline", help="run the end-to-end identification + tuning pipeline on a twin (resumable)",
                       **describe(__doc__))
    p.add_argument("--vehicle", default=None, help="vehicle name (see rotorlab list) or vehicle TOML (default "
                   "anteos-p2a2); with --log the twin to calibrate, e.g. from rotorlab vehicle new (default x500)")
    p.add_argument("--log", default=None, metavar="FLIGHT",
                   help="start from a flight log (.ulg, .bin/.log, or a ulog2csv folder): identify, calibrate the "
                        "twin, tune the autopilot's controller, validate in the twin, write the parameter file")
    p.add_argument("--controller", default=None, metavar="AUTOPILOT:PARAMS",
                   help="also fly an autopilot's own laws in the validation scenarios, beside the gain sets: "
                        "px4:FILE.params, ardupilot:FILE.parm, or px4:defaults")
    p.add_argument("--autopilot", default=None, choices=("px4", "ardupilot"),
                   help="with --log: the autopilot whose controller is tuned (default: the log's)")
    p.add_argument("--out", default=None, help="run folder (default runs/pipeline-VEHICLE[-quick]-seedN); "
                                               "re-running into it resumes, skipping unchanged stages")
    p.add_argument("--quick", action="store_true", help="half-length campaign, published best settings plus one alternative per grid, 50 bootstrap "
                                                  "replications, 100 Monte Carlo samples, one tuning start, 24 s hover")
    p.add_argument("--tiny", action="store_true", help=argparse.SUPPRESS)  # tests: seconds per stage
    p.add_argument("--executor", default="local", help="local (process pool), serial, dask (local cluster) or "
                   "dask://HOST:PORT (an existing scheduler: connect only to one you trust, it sends pickled "
                   "objects that run code here; docs/security.md)")
    p.add_argument("--workers", type=process_count, default=None,
                   help="worker processes, at most twice the CPUs (default: all cores)")
    p.add_argument("--seed", type=seed_int, default=0, help="master seed of every experiment, bootstrap and Monte Carlo")
    p.add_argument("--n-boot", type=bounded_int(MAX_SAMPLES), default=None,
                   help=f"bootstrap replications (default 1000, quick 50; at most {MAX_SAMPLES})")
    p.add_argument("--n-mc", type=bounded_int(MAX_SAMPLES), default=None,
                   help=f"Monte Carlo samples per gain set (default 1000, quick 100; at most {MAX_SAMPLES})")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def run(args) -> int:
    from rotorlab.pipeline import PipelineOptions, run_pipeline
    from rotorlab.vehicles import VEHICLES_DIR, load_vehicle, vehicle_path

    level = "tiny" if args.tiny else ("quick" if args.quick else "full")
    if args.log is not None:
        return run_log(args, level)
    if args.autopilot is not None:
        raise CLIError("--autopilot: expected it with --log FLIGHT (the twin pipeline tunes the rotorlab cascade)")
    controller = args.controller
    if controller is not None:
        head, sep, rest = controller.partition(":")
        if sep and rest not in ("", "defaults"):
            controller = f"{head}:{Path(rest).resolve()}"  # every worker reads the same file
    vehicle = args.vehicle or "anteos-p2a2"
    try:
        spec = load_vehicle(vehicle)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    if vehicle_path(vehicle) != VEHICLES_DIR / str(vehicle) / "vehicle.toml":
        # a path (vehicle_path's rule: a local folder of that name wins over a shipped name): absolute, so every
        # worker (a Dask worker may run elsewhere) reads the same file that load_vehicle just read
        vehicle = str(Path(vehicle).resolve())
    # named by the vehicle's name, never its path (`--vehicle /tmp/x.toml` made runs/pipeline-/tmp/...)
    out = Path(args.out or f"runs/pipeline-{spec.name}{'' if level == 'full' else '-' + level}-seed{args.seed}")
    opts = PipelineOptions(vehicle=vehicle, out=out, level=level, seed=args.seed, executor=args.executor,
                           workers=args.workers, progress=not args.no_progress, n_boot=args.n_boot, n_mc=args.n_mc,
                           controller=controller)
    return _run(run_pipeline, opts, out)


def _run(pipeline, opts, out: Path, *after) -> int:
    """Run ``pipeline(opts)`` and print its verdict (and ``after(out)``); bad input is a CLIError, Ctrl-C keeps the
    completed stages and exits 130."""
    try:
        pipeline(opts)
        print_verdict(out)
        for show in after:
            show(out)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    except KeyboardInterrupt:
        print(f"\ninterrupted: completed stages are kept in {out}; run the same command again to resume")
        return 130
    return 0


def run_log(args, level: str) -> int:
    """``rotorlab pipeline --log FLIGHT``: the log pipeline (:func:`rotorlab.pipeline.run_log_pipeline`)."""
    from rotorlab.pipeline import LogPipelineOptions, run_log_pipeline
    from rotorlab.vehicles import VEHICLES_DIR, vehicle_path

    if args.controller is not None:
        raise CLIError("--controller: expected it without --log (the log pipeline flies the log's parameters and the "
                       "tuned set itself)")
    if args.n_boot is not None or args.n_mc is not None:
        raise CLIError("--n-boot/--n-mc: expected them without --log (the log pipeline has no bootstrap or Monte "
                       "Carlo stage)")
    log = Path(args.log)
    vehicle = args.vehicle
    try:
        if vehicle is not None and vehicle_path(vehicle) != VEHICLES_DIR / str(vehicle) / "vehicle.toml":
            vehicle = str(Path(vehicle).resolve())  # every worker reads the same file
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    stem = log.stem if log.suffix else log.name
    out = Path(args.out or f"runs/pipeline-log-{stem}{'' if level == 'full' else '-' + level}-seed{args.seed}")
    opts = LogPipelineOptions(out=out, level=level, seed=args.seed,
                              executor=args.executor, workers=args.workers, progress=not args.no_progress,
                              log=log.resolve(), vehicle_file=vehicle, autopilot=args.autopilot)
    return _run(run_log_pipeline, opts, out, _print_parameter_file)


def _print_parameter_file(out: Path) -> None:
    import json

    from rotorlab.pipeline import stage_dir

    summary = stage_dir(out, "report") / "summary.json"
    if summary.is_file():
        name = json.loads(summary.read_text(encoding="utf-8")).get("parameter_file")
        print(f"\nparameter file: {stage_dir(out, 'report') / name}" if name else
              "\nno parameter file to fly: keep the log's parameters (report.md says why)")


def print_verdict(out: Path) -> None:
    """The report's verdict (which set to fly, its file, what got worse, what was not checked) on the terminal."""
    import json

    from rotorlab.pipeline import stage_dir
    from rotorlab.pipeline.stages.report import wrap

    report = stage_dir(out, "report")
    summary = report / "summary.json"
    if not summary.is_file():  # a pipeline without the report stage (stages=...) has no verdict to print
        return
    lines = json.loads(summary.read_text(encoding="utf-8")).get("verdict") or []
    if lines:
        print("\nverdict (" + str(report / "report.md") + "):")
        for sentence in lines:
            print("\n".join(wrap(sentence.replace("`", "").replace("report/gains/", f"{report}/gains/")
                                  .replace(" in the run folder", ""), 100)))
