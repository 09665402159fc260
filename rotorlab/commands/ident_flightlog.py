"""``rotorlab ident FLIGHT.ulg|FLIGHT.bin|CSV_DIR``: the flight-log route of the ident command (its arguments are
added by :func:`add_arguments`; rotorlab.commands.ident hands over when the log is a flight log)."""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, process_count

FLIGHT_LOG_SUFFIXES = (".ulg", ".bin", ".log")


def is_flight_log(path) -> bool:
    """A ULog, a DataFlash log or a folder (a ulog2csv export)."""
    p = Path(path)
    return p.is_dir() or p.suffix.lower() in FLIGHT_LOG_SUFFIXES


def add_arguments(p) -> None:
    g = p.add_argument_group("flight logs (FLIGHT.ulg, FLIGHT.bin/.log, ulog2csv folder; --out is a folder)")
    g.add_argument("--axis", default=None,
                   help="axes to identify, comma-separated (each must be identifiable); default: every axis with "
                        "excitation")
    g.add_argument("--window", action="append", default=[], metavar="START:STOP",
                   help="identification window in s of the log's time (repeatable); default: chosen automatically")
    g.add_argument("--holdout", type=float, default=0.4,
                   help="fraction of the airborne (or excitation) time held out at its end to score the models")
    g.add_argument("--rate-hz", type=float, default=None,
                   help="identification rate (default: the slowest logged signal of each axis)")
    g.add_argument("--imu-mount", default=None, metavar="HZ,DAMPING",
                   help="the IMU mount's natural frequency (Hz) and damping ratio, from the vehicle's description "
                        "(a twin's [imu] mount_frequency_hz, mount_damping_ratio): the mode in every axis's plant")
    g.add_argument("--allow-truncated", action="store_true",
                   help="read a ULog cut short (power loss) up to its last whole message")
    g.add_argument("--fleet", action="store_true",
                   help="LOG is a folder of flight logs: identify each (one model folder per log under --out) and "
                        "write the fleet summary fleet.csv and fleet.md")
    g.add_argument("--executor", default="local",
                   help="where a fleet's logs run: local (processes), serial, dask (a local cluster) or "
                        "dask://HOST:PORT (a scheduler sends pickled objects: connect only to one you trust, "
                        "docs/security.md)")
    g.add_argument("--workers", type=process_count, default=None,
                   help="worker processes for --fleet (at most twice the CPUs of this machine; default: the executor's)")


def _windows(items):
    out = []
    for it in items:
        a, sep, b = it.partition(":")
        try:
            lo, hi = float(a), float(b)
        except ValueError:
            raise CLIError(f"--window expects START:STOP in seconds, got {it!r}") from None
        if not sep or not hi > lo:
            raise CLIError(f"--window expects START:STOP with STOP > START, got {it!r}")
        out.append((lo, hi))
    return out or None


def _imu_mount(text):
    if text is None:
        return None
    try:
        hz, zeta = (float(x) for x in text.split(","))
    except ValueError:
        raise CLIError(f"--imu-mount expects HZ,DAMPING (e.g. 60,0.15), got {text!r}") from None
    if not (hz > 0 and zeta >= 0):
        raise CLIError(f"--imu-mount expects a frequency > 0 Hz and a damping ratio >= 0, got {text!r}")
    return hz, zeta


def run_flight_log(args) -> int:
    from rotorlab.atomic import check_output
    from rotorlab.ident.flightlogs.names import AXES
    from rotorlab.ident.flightlogs.run import identify_flight_log

    axes = None
    if args.axis is not None:
        axes = [a.strip() for a in args.axis.split(",") if a.strip()]
        bad = [a for a in axes if a not in AXES]
        if bad or not axes:
            raise CLIError(f"--axis: expected some of {', '.join(AXES)}, got {args.axis!r}")
    if not 0 < args.holdout < 1:
        raise CLIError(f"--holdout must be in (0, 1), got {args.holdout}")
    if args.rate_hz is not None and not args.rate_hz > 0:
        raise CLIError(f"--rate-hz must be > 0, got {args.rate_hz}")
    imu_mount = _imu_mount(args.imu_mount)
    if args.fleet:
        if imu_mount is not None:
            raise CLIError("--imu-mount is one vehicle's; a fleet's logs may come from several (leave it out)")
        return _run_fleet(args, axes, Path(args.out))
    # a flight log writes a folder (one model file per axis and the report), never over the log itself
    out = check_output(args.out, [args.log], what="folder")
    res = identify_flight_log(args.log, out, axes, windows=_windows(args.window), holdout=args.holdout,
                              rate_hz=args.rate_hz, allow_truncated=args.allow_truncated, imu_mount=imu_mount)
    log = res.log
    print(f"{log.path}: {log.autopilot} {log.version} ({log.format}), airborne {log.airborne_time_s():.1f} s "
          f"({log.airborne_source})")
    for axis, models in res.models.items():
        for kind, m in models.items():
            print(f"  {axis:5s} {kind:15s} {m.input} -> {m.output} at {1 / m.dt:.4g} Hz, {m.model.method}: "
                  f"VAF {m.vaf_holdout:.1f} % on the held-out {sum(w.duration_s for w in m.split.holdout):.1f} s")
    for n in log.notes + res.notes:
        print(f"  note: {n}")
    print(f"wrote {len(res.files)} files to {out} (report: {out / 'report.html'})")
    return 0


def _run_fleet(args, axes, out: Path) -> int:
    from rotorlab.atomic import check_output
    from rotorlab.executor import get_executor
    from rotorlab.ident.flightlogs.fleet import identify_fleet

    if out.exists() and not out.is_dir():
        raise CLIError(f"--out {out}: a fleet writes a folder (one model folder per log and the fleet summary); "
                       "expected a folder, got a file")
    if args.window:
        raise CLIError("--window is in one log's time; a fleet's windows are chosen per log (leave --window out)")
    out = check_output(out, [args.log], what="folder")  # never over the fleet folder itself
    with get_executor(args.executor, args.workers) as ex:
        res = identify_fleet(args.log, out, axes, executor=ex, holdout=args.holdout, rate_hz=args.rate_hz,
                             allow_truncated=args.allow_truncated)
    logs = {r["log"] for r in res.rows}
    print(f"{args.log}: {len(logs)} logs on {ex.name}, {len(res.failed)} not identified")
    for r in res.rows:
        if r["error"]:
            print(f"  {r['log']}: {r['error']}")
        else:
            print(f"  {r['log']} {r['axis']:5s} {r['kind']:15s} {r['method']}: VAF {r['vaf_holdout_pct']:.1f} %")
    print(f"wrote {out / 'fleet.csv'} and {out / 'fleet.md'}")
    return 0
