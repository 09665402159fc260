"""``rotorlab run SCENARIO --vehicle V [--scene S] [--gains NAME|FILE] [--duration S] [--seed N] [--out DIR]``."""

from __future__ import annotations

import time
from pathlib import Path


def add_parser(sub):
    p = sub.add_parser("run", help="run a scenario headless and write a run folder (log.parquet, run.json)")
    p.add_argument("scenario", help="scenario name (see `rotorlab list`)")
    p.add_argument("--vehicle", default="anteos-p2a2", help="vehicle name or vehicle TOML path")
    p.add_argument("--scene", default=None, help="scene (default: the scenario's first scene)")
    p.add_argument("--gains", default=None, help="gain set name shipped with the vehicle, or a gains TOML file")
    p.add_argument("--duration", type=float, default=None, help="duration, s (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=None, help="run folder (default runs/SCENARIO-VEHICLE-seedN)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario option (repeatable); values are parsed as TOML scalars")
    p.add_argument("--rerun", default=None, metavar="FILE.rrd",
                   help="also write a rerun recording (3D scene, poses, thrust, signals); open it with `rotorlab view`")
    return p


def _options(items) -> dict:
    import tomllib

    from rotorlab.cli import CLIError

    out = {}
    for it in items:
        if "=" not in it:
            raise CLIError(f"--option expects KEY=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        try:
            out[k.strip()] = tomllib.loads(f"v = {v}")["v"]
        except tomllib.TOMLDecodeError:
            out[k.strip()] = v
    return out


def run(args) -> int:
    from rotorlab.cli import CLIError
    from rotorlab.errors import RotorlabError
    from rotorlab.sim.runner import run_scenario

    out = Path(args.out or f"runs/{args.scenario}-{Path(str(args.vehicle)).stem}-seed{args.seed}")
    rrd = None
    if args.rerun:
        from rotorlab.sim.rerun_log import check_rrd_path

        try:
            rrd = check_rrd_path(args.rerun)  # before the run: a bad path must not cost a simulation
        except RotorlabError as exc:
            raise CLIError(str(exc)) from None
    t0 = time.perf_counter()
    try:
        res = run_scenario(args.scenario, args.vehicle, scene=args.scene, gains=args.gains, seed=args.seed,
                           duration_s=args.duration, out=out, options=_options(args.option), progress=True,
                           record_poses=rrd is not None)
        if rrd is not None:
            from rotorlab.sim.rerun_log import record_run

            record_run(res, rrd)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    wall = time.perf_counter() - t0
    info = res.info
    sim_s = res.log.n * info["control_dt_s"]
    print(f"{info['scenario']} on {info['vehicle']} ({info['scene']}), gains {info['gains']}, seed {info['seed']}: "
          f"{sim_s:.1f} s simulated in {wall:.2f} s ({sim_s / wall:.1f}x real time)")
    for key, val in info.get("metrics", {}).items():
        print(f"  {key}: {val}")
    if res.stopped:
        print(f"stopped early: {res.stopped}")
    print(f"wrote {res.out_dir}" + (f" and {rrd}" if rrd is not None else ""))
    return 1 if res.stopped else 0
