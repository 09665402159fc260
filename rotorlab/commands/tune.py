"""Tune the attitude cascade (outer PD on the angle, inner PID on the rate) to a specification by structured
H-inf optimisation, and write the gains TOML that rotorlab run --gains reads; or, with --autopilot, tune PX4's or
ArduPilot's own loops on every axis against the generic multirotor spec derived from the models and write the
tuned parameters in the autopilot's file format (docs/autopilot-tuning.md).

Prints the tuned gains and every goal of the spec with its value (<= 1 passes), hard or soft, pass or fail.
Exit status 1 when a hard goal fails. The spec is a TOML file or a shipped name (anteos-p2a2,
anteos-a2minib); the models are JSON files from rotorlab ident, or hand-written {num, den, dt, delay_s}.
A model whose units (carried in its file) differ from the spec's (% in, deg/s out) is refused with the factors
that convert it, or converted with --convert-units; a model without units is taken as in the spec's and the
run says so (docs/units.md).
"""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, bounded_int, describe, process_count, seed_int
from rotorlab.errors import RotorlabError

#: bounds of the counts (each start runs up to --max-iter optimiser iterations of a few seconds)
MAX_STARTS = 1000
MAX_ITER = 10000

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("tune", help="structured H-inf tuning of the attitude cascade", **describe(__doc__))
    p.add_argument("--model", required=True, action="append",
                   help="model JSON (as written by 'rotorlab ident', or {num, den, dt, delay_s}); repeat the "
                        "option to tune on several models at once")
    p.add_argument("--spec", help="spec TOML file or built-in name (anteos-p2a2, anteos-a2minib); with --autopilot, "
                                  "an autopilot spec (default: the generic spec derived from the models)")
    p.add_argument("--autopilot", choices=("px4", "ardupilot"),
                   help="tune this autopilot's attitude and rate loops; --model [AXIS=]FILE per axis (roll, pitch, "
                        "yaw; a bare FILE serves every axis of --axes), --out a .params (PX4) or .parm (ArduPilot)")
    p.add_argument("--params", help="with --autopilot: the parameters flown today (.params/.parm); filters and loop "
                                    "rate come from them, and they are a baseline (default: the autopilot's defaults)")
    p.add_argument("--axes", default="roll,pitch,yaw", help="with --autopilot: axes a bare --model FILE serves")
    p.add_argument("--loop-hz", type=float, help="with --autopilot: loop rate, Hz (default: the parameters' "
                                                 "IMU_GYRO_RATEMAX / SCHED_LOOP_RATE)")
    p.add_argument("--spec-out", help="with --autopilot: write the generated spec TOML here")
    p.add_argument("--match", help="with --autopilot: hold the tuned set to this baseline's robustness (file, "
                                   "defaults, px4-autotune): its disk margin and at least its gyro-noise allowance, not the most robust "
                                   "baseline's; 'all': beat every baseline at once, at the most robust one's margin with "
                                   "the noisiest one's gyro-noise allowance (docs/autopilot-tuning.md)")
    p.add_argument("--filters", choices=("keep", "search"), default="keep",
                   help="with --autopilot: keep the flown filter cutoffs (default) or search them with the gains "
                        "(the gyro and D-term low-passes, up to 2.5x the flown cutoffs; 16 tunings)")
    p.add_argument("--start", default="standard",
                   help="start gains: a gains TOML file or a gain-set name of the spec's vehicle")
    p.add_argument("--out", required=True, help="gains TOML (parameter file with --autopilot) to write; when a hard "
                                                "goal fails nothing is written there and the result goes to "
                                                "OUT.failed.toml (.failed.params/.parm), marked as failing")
    p.add_argument("--starts", type=bounded_int(MAX_STARTS), default=None,
                   help=f"number of starts: the start gains, then random starts; the best is kept (at most "
                        f"{MAX_STARTS}; default 4)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the random starts")
    p.add_argument("--jobs", type=process_count, default=2,
                   help="processes for the starts (at most twice the CPUs of this machine; default: %(default)s)")
    p.add_argument("--max-iter", type=bounded_int(MAX_ITER), default=None,
                   help=f"outer iterations per start (at most {MAX_ITER}; default 40; 30 per axis with --autopilot)")
    p.add_argument("--convert-units", action="store_true",
                   help="tune on a model whose input/output units differ from the spec's (e.g. rad/s and a "
                        "normalised command against deg/s and %%) after scaling it into them; without it such a "
                        "model is refused with the factors to use (docs/units.md)")
    return p


def _start_gains(start: str, spec_path):
    from rotorlab.gains import load_gains

    p = Path(start)
    if p.suffix == ".toml" or p.exists():
        return load_gains(p)

    from rotorlab.config import check_name, read_toml
    from rotorlab.vehicles import gains_path, list_vehicles

    meta = read_toml(spec_path, "spec").get("meta", {})
    vehicle = meta.get("vehicle") if isinstance(meta, dict) else None
    if not vehicle or not isinstance(vehicle, str):
        raise CLIError(f"--start '{start}' is not a file and the spec names no [meta] vehicle to look it up in")
    # a name from a file: never a path (a "../" in it read a gains file from elsewhere)
    check_name(vehicle, spec_path, "meta.vehicle")
    if vehicle not in list_vehicles():
        raise CLIError(f"{spec_path}: field 'meta.vehicle': --start '{start}' is a gain-set name, looked up among "
                       f"the shipped vehicles' sets; expected one of {list_vehicles()}, got {vehicle!r} (give "
                       "--start FILE.toml for another vehicle)")
    return load_gains(gains_path(vehicle, start))


def run(args) -> int:
    if args.autopilot:
        from rotorlab.commands._tune_autopilot import run_autopilot

        return run_autopilot(args)
    if not args.spec:
        raise CLIError("--spec is required (or --autopilot px4|ardupilot to tune an autopilot's own loops)")
    args.starts = args.starts or 4
    args.max_iter = args.max_iter or 40
    from rotorlab import atomic
    from rotorlab.gains import save_gains
    from rotorlab.ident.modelio import load_model, model_io_units
    from rotorlab.tune.cascade import PlantModel
    from rotorlab.tune.goals import format_report, tune_cascade
    from rotorlab.tune.spec import builtin_specs, load_spec, model_in_spec_units

    try:
        atomic.check_output(args.out, args.model)  # before minutes of tuning
        spec = load_spec(args.spec)
        spec_path = builtin_specs().get(str(args.spec), args.spec)
        models = []
        for path in args.model:
            sys_, delay_s, meta = load_model(path)
            sys_, note = model_in_spec_units(sys_, model_io_units(meta, path), spec, path, args.convert_units)
            if note:
                print(f"model {path}: {note}")
            models.append(PlantModel(sys_, delay_s, name=Path(path).stem))
        start = _start_gains(args.start, spec_path)
        # every input is recorded now (models, spec, start gains): neither output may replace one
        out = Path(args.out)
        for path in (out, out.with_name(out.stem + ".failed.toml")):
            atomic.check_output(path)
        res = tune_cascade(spec, models, start, starts=args.starts, seed=args.seed, n_jobs=args.jobs,
                           max_iter=args.max_iter, name=Path(args.out).stem)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    failed = [r for r in res.report if r.hard and not r.passed]
    out = Path(args.out)
    if failed:
        # a gains file that misses a hard goal must never pass for a tuned one: it goes beside --out, its header
        # says which goals failed, and --out is left as it was
        out = out.with_name(out.stem + ".failed.toml")
        header = (f"# FAILED: rotorlab tune did not meet {len(failed)} hard goal(s) of spec '{spec.name}': "
                  + "; ".join(f"{r.goal} on {r.model}" for r in failed) + "\n# do not fly these gains\n")
        atomic.write_text(out, header + res.gains.to_toml())
    else:
        save_gains(res.gains, out)
    g = res.gains[spec.axis]
    print(f"spec {spec.name}: {len(models)} model(s), {len(res.history) - 1} iterations, {res.time_s:.1f} s")
    print(f"outer PD : kp={g.outer.kp:.4f} kd={g.outer.kd:.4f} tf={g.outer.tf:.4f} b={g.outer.b:.4f} c={g.outer.c:.4f}")
    print(f"inner PID: kp={g.inner.kp:.4f} ki={g.inner.ki:.4f} kd={g.inner.kd:.4f} tf={g.inner.tf:.4f} "
          f"b={g.inner.b:.4f} c={g.inner.c:.4f}")
    print(format_report(res.report))
    if failed:
        names = ", ".join(r.goal for r in failed)
        print(f"objective (max soft goal) {res.objective:.4f}; HARD GOALS NOT MET ({names}): "
              f"{args.out} not written; the gains are in {out}, marked as failing")
        return 1
    print(f"objective (max soft goal) {res.objective:.4f}; wrote {out}")
    return 0
