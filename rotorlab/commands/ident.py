"""Identify a discrete model from a log and write the model JSON that rotorlab tune reads.

Prints the model (time base, order, delay, poles and zeros in rad/s with natural frequency and damping, DC
gain with units) and its VAF on the identification data and, with --cv-log or --cv-split, on
cross-validation data. Methods (rotorlab.ident.methods, the table the pipeline uses): pi-moesp (MOESP with
past-input instruments), pbsid (predictor-based, for closed-loop data), lms-kung (LMS impulse response + Kung
realisation), arx (least-squares ARX of --order), oe-greybox (output-error grey-box fit of --structure) and
hinf-match (H-inf matching of
--structure to a PI-MOESP model). The LOG is a rotorlab Parquet log or a CSV file with a
header row; --column-map renames CSV columns, --resample interpolates uneven time stamps. The time column is
read in seconds, or in the unit its type, the Parquet units metadata or --time-unit gives; a column whose steps
are not plausible seconds is refused (docs/units.md). The model file carries the units of its input and output
(from the Parquet metadata or --units) for rotorlab tune to check.

A flight log (PX4 .ulg, a ulog2csv folder, ArduPilot .bin/.log) is identified per axis instead: the closed loop
(rate set-point -> rate), the plant (rate-loop output -> rate) and the plant through the autopilot's controller,
with one model file per axis and report.html written into the --out folder (docs/flight-logs.md).
"""

from __future__ import annotations

import numpy as np

from rotorlab.cli import CLIError, describe, positive_int
from rotorlab.errors import ConfigError, DataError, UnknownNameError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.

STRUCTURES = ("rate-tf", "rigid-rig", "pitch")


def add_parser(sub):
    p = sub.add_parser("ident", help="identify a model from a log and write it as JSON", **describe(__doc__))
    p.add_argument("log", help="Parquet log (rotorlab format), CSV with a 't' column (see --column-map), or a flight "
                               "log: FLIGHT.ulg, FLIGHT.bin/.log or a ulog2csv folder")
    # checked in run() against rotorlab.ident.methods.METHODS, the table the pipeline uses: importing it here
    # would load the identification stack before every command
    # --method/--input/--output are required for Parquet/CSV logs (checked in run()); a flight log needs none
    p.add_argument("--method",
                   help="identification method of rotorlab.ident.methods (pi-moesp, pbsid, lms-kung, arx, "
                        "oe-greybox, hinf-match)")
    p.add_argument("--input", help="input column(s), comma-separated")
    p.add_argument("--output", help="output column(s), comma-separated")
    p.add_argument("--order", type=positive_int, default=4, help="model order (black-box methods)")
    p.add_argument("--horizon", type=positive_int, default=40, help="PI-MOESP block rows p (40 as published)")
    p.add_argument("--past", type=positive_int, default=11, help="PBSID past window, samples (11 as published)")
    p.add_argument("--future", type=positive_int, default=7, help="PBSID future window, samples (7 as published)")
    p.add_argument("--taps", type=positive_int, default=100, help="LMS impulse-response taps")
    p.add_argument("--delay", default="0", help="input delay in samples, or 'auto' to estimate it")
    p.add_argument("--max-delay", type=positive_int, default=20, help="largest delay tried by --delay auto, samples")
    p.add_argument("--structure", default="rate-tf", choices=STRUCTURES,
                   help="grey-box structure for oe-greybox / hinf-match (rate-tf: K(s+z)/(s^2+as+b))")
    p.add_argument("--column-map", action="append", default=[], metavar="OURS=FILE",
                   help="use the file's column FILE as OURS, e.g. t=time or q=pitch_rate (repeatable, or comma-separated)")
    p.add_argument("--time-unit", default=None, choices=("s", "ms", "us", "ns", "auto"),
                   help="unit of the log's time column (default: the column's type or the Parquet units metadata, "
                        "else seconds where the steps are plausible in seconds and a refusal naming the units that "
                        "fit where they are not; auto: take the one unit that fits); see docs/units.md")
    p.add_argument("--units", action="append", default=[], metavar="COLUMN=UNIT",
                   help="unit of a column, e.g. q=deg/s or u=%% (repeatable, or comma-separated; overrides the "
                        "Parquet units metadata); the model file carries its input and output units and rotorlab "
                        "tune checks them against the spec's (docs/units.md)")
    p.add_argument("--resample", action="store_true",
                   help="interpolate onto a uniform grid at the median time step instead of refusing uneven time stamps")
    cv = p.add_mutually_exclusive_group()
    cv.add_argument("--cv-log", help="separate cross-validation log")
    cv.add_argument("--cv-split", type=float, help="fraction of LOG used to identify; the rest cross-validates")
    p.add_argument("--out", required=True, help="model JSON to write (a folder for a flight log)")
    from rotorlab.commands.ident_flightlog import add_arguments

    add_arguments(p)
    return p


def parse_column_map(items) -> dict:
    """``["t=time", "q=pitch_rate,u=cmd"]`` -> ``{"t": "time", "q": "pitch_rate", "u": "cmd"}``."""
    out = {}
    for item in (x.strip() for it in items for x in it.split(",")):
        if not item:
            continue
        ours, sep, theirs = item.partition("=")
        if not sep or not ours.strip() or not theirs.strip():
            raise CLIError(f"--column-map expects OURS=FILE_COLUMN (e.g. t=time), got '{item}'")
        out[ours.strip()] = theirs.strip()
    return out


def parse_units(items) -> dict:
    """``["q=deg/s", "u=%,y=rad"]`` -> ``{"q": "deg/s", "u": "%", "y": "rad"}``."""
    out = {}
    for item in (x.strip() for it in items for x in it.split(",")):
        if not item:
            continue
        col, sep, unit = item.partition("=")
        if not sep or not col.strip() or not unit.strip():
            raise CLIError(f"--units expects COLUMN=UNIT (e.g. q=deg/s), got '{item}'")
        out[col.strip()] = unit.strip()
    return out


def _structure(name: str):
    from rotorlab.ident import structures

    return {"rate-tf": structures.rate_tf_structure, "rigid-rig": structures.rigid_rig_structure,
            "pitch": structures.pitch_structure}[name]()


def _identify(args, u, y, dt, delay):
    """Returns an IdentifiedModel (discrete, delay in samples) and the object to save."""
    from rotorlab.ident.methods import METHODS
    from rotorlab.ident.model import IdentifiedModel
    from rotorlab.lti import c2d_zoh

    method = METHODS[args.method]
    flags = {"order": args.order, "horizon": args.horizon, "past": args.past, "future": args.future,
             "taps": args.taps}
    if not method.greybox:
        model = method.fit(u, y, dt=dt, delay=delay, **{k: flags[k] for k in method.settings})
        return model, model
    settings = {k: flags[k] for k in method.settings if k != "structure"}
    res = method.fit(u, y, dt=dt, delay=delay, structure=_structure(args.structure), rng=0, **settings)
    if args.method == "hinf-match":
        print(f"H-inf matching of '{args.structure}' to PI-MOESP n={args.order}: "
              f"||G_W (G_ns - G_s)||_inf = {res.norm:.4g} at {res.w_peak:.3g} rad/s")
        for k, v in res.params.items():
            print(f"  {k:>10s} = {v:.6g}")
    else:
        print(res.summary())
    disc = IdentifiedModel(sys=c2d_zoh(res.sys, dt), delay=delay, method=args.method,
                           settings={"structure": args.structure})
    return disc, res


def run(args) -> int:
    from rotorlab.atomic import check_output
    from rotorlab.commands.ident_flightlog import is_flight_log, run_flight_log
    from rotorlab.ident.logs import check_identifiable, load_log
    from rotorlab.ident.methods import get_method
    from rotorlab.ident.metrics import simulate, vaf
    from rotorlab.ident.modelio import save_model

    if is_flight_log(args.log):
        return run_flight_log(args)
    missing = [f"--{k}" for k in ("method", "input", "output") if getattr(args, k) is None]
    if missing:
        raise CLIError(f"the following arguments are required for a Parquet or CSV log: {', '.join(missing)}")
    check_output(args.out, [args.log, args.cv_log])  # never over an input log, before any work

    try:
        get_method(args.method)
    except UnknownNameError as exc:
        raise CLIError(f"--method: {exc}") from None
    u_cols = [c.strip() for c in args.input.split(",") if c.strip()]
    y_cols = [c.strip() for c in args.output.split(",") if c.strip()]
    cmap = parse_column_map(args.column_map)
    col_units = parse_units(args.units)
    unknown = sorted(set(col_units) - set(u_cols + y_cols))
    if unknown:
        raise CLIError(f"--units names column(s) {unknown} that are neither --input nor --output; expected one of "
                       f"{', '.join(u_cols + y_cols)}")
    try:
        log = load_log(args.log, columns=u_cols + y_cols, column_map=cmap, resample=args.resample,
                       units=col_units, time_unit=args.time_unit)
        if log.time_unit != "s":
            print(f"time column of {args.log} read in {log.time_unit}: dt = {log.dt:.6g} s")
        if args.cv_log:
            id_log, cv_log = log, load_log(args.cv_log, columns=u_cols + y_cols, column_map=cmap,
                                           resample=args.resample, units=col_units, time_unit=args.time_unit)
            if abs(cv_log.dt - log.dt) > 1e-9 * log.dt:
                raise CLIError(f"--cv-log {args.cv_log} has dt = {cv_log.dt} s, the log {log.dt} s")
        elif args.cv_split is not None:
            if not 0 < args.cv_split < 1:
                raise CLIError(f"--cv-split must be in (0, 1), got {args.cv_split}")
            id_log, cv_log = log.split(args.cv_split)
        else:
            id_log, cv_log = log, None
        u, y = id_log.to_arrays(u_cols, y_cols)
        dt = id_log.dt
        if args.method in ("pi-moesp", "hinf-match"):
            check_identifiable(id_log, u_cols, y_cols, args.order, args.horizon)
        elif args.method == "pbsid":
            check_identifiable(id_log, u_cols, y_cols, args.order, args.past, args.future)
        if args.delay == "auto":
            from rotorlab.ident.delay import estimate_delay

            delay = estimate_delay(u, y, args.max_delay)
            print(f"estimated delay: {delay} samples ({delay * dt:.4g} s)")
        else:
            try:
                delay = int(args.delay)
            except ValueError:
                raise CLIError(f"--delay must be a whole number of samples or 'auto', got {args.delay!r}") from None
            if delay < 0:
                raise CLIError(f"--delay must be >= 0, got {delay}")
            if delay > len(u) // 2:
                # shifting by the delay leaves N - delay samples to identify from; past half the log the
                # methods run for minutes on windows too short to mean anything
                raise CLIError(f"--delay {delay} samples leaves {len(u) - delay} of the log's {len(u)} samples; "
                               f"expected at most {len(u) // 2} (half the log)")
        disc, to_save = _identify(args, u, y, dt, delay)
        fit = vaf(y, simulate(disc, u, x0="estimate", y=y))
        if not np.all(np.isfinite(fit)):
            scale = float(np.nanmax(np.abs(np.concatenate([u.ravel(), y.ravel()]))))
            raise DataError(f"{args.log}: identification failed numerically (VAF {fit}); expected signals of "
                            f"moderate scale, got values up to {scale:.3g}; rescale the log")
        print(f"{args.method}: VAF on identification data {', '.join(f'{v:.2f} %' for v in fit)}")
        score = fit
        if cv_log is not None:
            uc, yc = cv_log.to_arrays(u_cols, y_cols)
            score = vaf(yc, simulate(disc, uc, x0="estimate", y=yc))
            print(f"{args.method}: VAF on cross-validation data {', '.join(f'{v:.2f} %' for v in score)}")
    except (DataError, ConfigError, ValueError) as exc:
        raise CLIError(str(exc)) from exc
    units = {c: log.units[c] for c in u_cols + y_cols if c in log.units}
    missing = [c for c in u_cols + y_cols if c not in units]
    if missing:
        print(f"no unit for {', '.join(missing)} (the log declares none): the model carries none for "
              f"{'it' if len(missing) == 1 else 'them'}, and rotorlab tune takes a signal without a unit as the "
              "spec's; give them with --units COLUMN=UNIT (docs/units.md)")
    from rotorlab.ident.modelio import describe_model

    print("\n".join(describe_model(disc.sys, delay * dt, units, u_cols, y_cols)))
    save_model(args.out, to_save, vaf=np.asarray(score), input=u_cols, output=y_cols, units=units,
               delay_s=delay * dt, extra={"log": str(args.log), "cv": args.cv_log or args.cv_split})
    print(f"wrote {args.out}")
    return 0
