"""Run a scenario headless on a vehicle's twin and write a run folder (log.parquet, run.json).

Prints a short summary: the real-time factor of the closed loop (model build excluded), the scenario's key
metrics with units and, for set-point runs, one line per step. --json prints everything (run.json's content
plus timings) as one JSON object instead, for scripts.
"""

from __future__ import annotations

import json
from pathlib import Path

from rotorlab.cli import CLIError, describe, seed_int
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.

#: at most this many per-step lines in the summary (the rest are in run.json)
MAX_STEP_LINES = 16


def add_parser(sub):
    p = sub.add_parser("run", help="run a scenario headless and write a run folder (log.parquet, run.json)",
                       **describe(__doc__))
    p.add_argument("scenario", help="scenario name (see rotorlab list; rotorlab list --scenario NAME shows its options)")
    p.add_argument("--vehicle", default="anteos-p2a2", help="vehicle name or vehicle TOML path")
    p.add_argument("--scene", default=None, help="scene (default: the scenario's first scene)")
    p.add_argument("--gains", default=None, help="gain set name shipped with the vehicle, or a gains TOML file "
                                                 "(default: the vehicle's standard set)")
    p.add_argument("--controller", action="append", default=[], metavar="NAME|AUTOPILOT:PARAMS|FILE",
                   help="fly a discrete controller in place of the cascade (repeatable): a design name "
                        "(modified-pid, hinf-loopshaping, hinf-loopshaping-aw; TUHH), an autopilot's own laws "
                        "(px4:defaults, px4:FILE.params, ardupilot:defaults, ardupilot:FILE.parm; docs/autopilots.md) "
                        "or a .json/.toml state-space controller file (see rotorlab.sim.control.statespace)")
    p.add_argument("--duration", type=float, default=None, help="duration, s (default: the scenario's)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the sensor noise and the disturbances")
    p.add_argument("--out", default=None, help="run folder (default runs/SCENARIO-VEHICLE-seedN)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario option (repeatable); values are parsed as TOML scalars or lists")
    p.add_argument("--rerun", default=None, metavar="FILE.rrd",
                   help="also write a rerun recording (3D scene, poses, thrust, signals); open it with rotorlab view")
    p.add_argument("--autopilot-log", default=None, metavar="FILE.ulg|FILE.bin",
                   help="also write the flight as the autopilot's log (scenario autopilot-sysid): .ulg PX4 ULog, "
                        ".bin ArduPilot DataFlash")
    p.add_argument("--json", action="store_true", help="print one JSON object (run.json plus timings) instead of "
                                                       "the summary; no progress bar")
    return p


def parse_options(items) -> dict:
    """``KEY=VALUE`` strings -> dict; values parsed as TOML (``2.5``, ``true``, ``[1, 2]``), else kept as text."""
    import tomllib

    from rotorlab.config import MAX_DEPTH, check_depth

    out = {}
    for it in items:
        if "=" not in it:
            raise CLIError(f"--option expects KEY=VALUE, got '{it}'")
        k, v = it.split("=", 1)
        try:
            out[k.strip()] = check_depth(tomllib.loads(f"v = {v}")["v"], "--option")
        except tomllib.TOMLDecodeError:
            out[k.strip()] = v
        except (RecursionError, ValueError):  # nested too deeply; an integer beyond 4300 digits
            raise CLIError(f"--option {k.strip()}: expected a TOML scalar or a list nested at most {MAX_DEPTH} "
                           f"deep, got {len(v)} characters that are neither") from None
    return out


def summary_lines(res, rrd=None) -> list[str]:
    """The human summary of a run: at most 40 lines of at most 160 characters, every number with its unit."""
    from rotorlab.keymetrics import flatten_metrics, fmt, key_rows

    info, tm = res.info, res.timing
    sim_s = res.log.n * info["control_dt_s"]
    loop_s = max(tm.get("sim_s", float("nan")), 1e-9)  # an interrupted run may have no closed-loop time
    ctl = ", ".join(c["name"] for c in info.get("controller", []))
    flown = f"controller {ctl} (cascade gains {info['gains'] or '-'} elsewhere)" if ctl else f"gains {info['gains'] or '-'}"
    L = [f"{info['scenario']} on {info['vehicle']} ({info['scene']}), {flown}, seed {info['seed']}",
         f"simulated {sim_s:.1f} s in {loop_s:.2f} s of closed loop: {sim_s / loop_s:.1f}x real time "
         f"(model build {tm.get('build_s', 0.0):.2f} s and scoring/writing {tm.get('score_s', 0.0):.2f} s not counted)"]
    if res.stopped:
        L.append(f"STOPPED EARLY: {res.stopped}")
    flat = flatten_metrics(info.get("metrics", {}))
    rows = key_rows(info["scenario"], flat, rest=False)
    if not rows:  # a scenario without key metrics: its first results, labelled by key
        rows = key_rows(info["scenario"], flat, rest=True)[:12]
    if rows:
        width = max(len(r[1]) for r in rows)
        sw = (info.get("notes") or {}).get("switch_s")
        phased = "after_switch" in info.get("metrics", {})
        L.append(f"metrics (after the in-flight gain switch at {fmt(sw)} s):" if phased else "metrics:")
        L += [f"  {label:<{width}}  {fmt(vals[0])} {unit}".rstrip() for _, label, unit, vals in rows]
    steps = info.get("metrics", {}).get("steps") or []
    if steps:
        cols = ((6, "from"), (6, "to"), (6, "at"), (9, "rise"), (10, "overshoot"), (9, "settling"), (15, "steady-state"))
        units = ("[deg]", "[deg]", "[s]", "[s]", "[%]", "[s]", "error [deg]")
        L.append(f"steps of {info['metrics'].get('axis', 'the angle')}:")
        L.append("  " + " ".join(f"{n:>{w}}" for w, n in cols))
        L.append("  " + " ".join(f"{u:>{w}}" for (w, _), u in zip(cols, units)))
        for m in steps[:MAX_STEP_LINES]:
            vals = (m.get("from_deg"), m.get("to_deg"), m.get("t_s"), m.get("rise_time_s"), m.get("overshoot_pct"),
                    m.get("settling_time_s"), m.get("steady_state_error"))
            L.append("  " + " ".join(f"{fmt(v, 4):>{w}}" for (w, _), v in zip(cols, vals)))
        if len(steps) > MAX_STEP_LINES:
            L.append(f"  ... {len(steps) - MAX_STEP_LINES} more steps in run.json")
    n_more = len(key_rows(info["scenario"], flat, rest=True)) - len(rows)
    where = f"{res.out_dir}" if res.out_dir else "memory"
    L.append(f"wrote {where} (log.parquet, run.json" + (f"; {n_more} more metrics there" if n_more > 0 else "") + ")"
             + (f" and {rrd}" if rrd is not None else ""))
    return L


def run(args) -> int:
    from rotorlab.sim.runner import INTERRUPTED, run_scenario
    from rotorlab.vehicles import load_vehicle

    try:
        vehicle = load_vehicle(args.vehicle)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    # the vehicle's own name (a safe name, rotorlab.config.check_name), not its path: `--vehicle ../x/vehicle.toml`
    # must not name the folder "vehicle"
    out = Path(args.out or f"runs/{args.scenario}-{vehicle.name}-seed{args.seed}")
    rrd = None
    if args.rerun:
        from rotorlab.sim.rerun_log import check_rrd_path

        try:
            rrd = check_rrd_path(args.rerun)  # before the run: a bad path must not cost a simulation
        except RotorlabError as exc:
            raise CLIError(str(exc)) from None
    if args.autopilot_log:
        from rotorlab.twinlogs import log_format

        try:
            log_format(args.autopilot_log)  # before the run: a bad name must not cost a simulation
        except RotorlabError as exc:
            raise CLIError(f"--autopilot-log: {exc}") from None
    from rotorlab.atomic import check_output

    inputs = [vehicle.path, *(c for c in args.controller if Path(c).suffix in (".json", ".toml"))]
    if args.gains and Path(args.gains).suffix == ".toml":
        inputs.append(args.gains)
    try:
        check_output(out, inputs, "--out", what="folder")
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    try:
        controller = None
        if args.controller:
            from rotorlab.designs import resolve_controller

            controller = []
            for c in args.controller:
                r = resolve_controller(c, vehicle)
                controller.extend(r if isinstance(r, list) else [r])
        res = run_scenario(args.scenario, vehicle, scene=args.scene, gains=args.gains, seed=args.seed,
                           duration_s=args.duration, out=out, options=parse_options(args.option),
                           progress=not args.json, record_poses=rrd is not None, controller=controller,
                           interruptible=True)
        if rrd is not None:
            from rotorlab.sim.rerun_log import record_run

            record_run(res, rrd)
        if args.autopilot_log and not res.stopped:
            from rotorlab.twinlogs import run_to_log

            run_to_log(res, args.autopilot_log)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    if args.json:
        doc = {**res.info, "timing_s": res.timing,
               "real_time_factor": res.log.n * res.info["control_dt_s"] / res.timing["sim_s"],
               "out": str(res.out_dir), "recording": str(rrd) if rrd is not None else None}
        print(json.dumps(doc, indent=1, allow_nan=False))
    else:
        print("\n".join(summary_lines(res, rrd)))
    if res.stopped == INTERRUPTED:
        return 130
    return 1 if res.stopped else 0
