"""``rotorlab montecarlo SCENARIO --vehicle V --n 1000 --vary mass,inertia,delay,wind [--executor ...]``:
scenario Monte Carlo over seeded parameter distributions of the twin.

Each sample ``i`` draws its parameters and its run seed from child ``i`` of ``SeedSequence(--seed)``, so the
numbers do not depend on the executor or the batch size. The varied twin is ``dataclasses.replace`` of the
vehicle spec. Results: one Parquet of metrics per batch (``batch-0000.parquet``, ...) and ``summary.json``
(quantiles of every metric and the fraction of runs that stopped early). Runs go through the process/Dask
executor; batched in-process MuJoCo stepping (``mujoco.batch``) is not used yet.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

#: parameter -> (distribution, spread): multiplicative uniform +-spread for mass and inertia, additive
#: uniform [0, spread] s of extra transport delay, mean wind uniform in [0, spread] m/s
VARY = {"mass": 0.10, "inertia": 0.10, "delay": 0.02, "wind": 5.0}
WIND_OPTION = {"gust": "mean_wind_mps", "hover": "wind_mps", "prbs-flight": "wind_mps"}


def add_parser(sub):
    p = sub.add_parser("montecarlo", help="scenario Monte Carlo over seeded vehicle/wind parameter spreads")
    p.add_argument("scenario")
    p.add_argument("--vehicle", default="anteos-p2a2")
    p.add_argument("--gains", default=None, help="gain set name or gains TOML (default standard)")
    p.add_argument("--n", type=int, default=100, help="number of runs")
    p.add_argument("--vary", default="mass,inertia,delay", help=f"comma list from {','.join(VARY)}")
    p.add_argument("--duration", type=float, default=None, help="run duration, s (default: the scenario's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--batch", type=int, default=50, help="runs per Parquet batch")
    p.add_argument("--executor", default="local", help="local, serial, dask or dask://HOST:PORT")
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--out", default=None, help="output folder (default runs/montecarlo-SCENARIO-VEHICLE-seedN)")
    return p


def draw(vehicle, vary, seed_seq):
    """Varied vehicle spec, scenario options and run seed of one sample."""
    rng = np.random.default_rng(seed_seq)
    spec, params = vehicle, {}
    if "mass" in vary:
        params["mass_scale"] = float(rng.uniform(1 - VARY["mass"], 1 + VARY["mass"]))
        spec = dataclasses.replace(spec, mass_kg=spec.mass_kg * params["mass_scale"])
    if "inertia" in vary:
        params["inertia_scale"] = float(rng.uniform(1 - VARY["inertia"], 1 + VARY["inertia"]))
        spec = dataclasses.replace(spec, inertia_kgm2=tuple(x * params["inertia_scale"] for x in spec.inertia_kgm2))
    if "delay" in vary:
        params["extra_delay_s"] = float(rng.uniform(0.0, VARY["delay"]))
        spec = dataclasses.replace(spec, rotor=dataclasses.replace(
            spec.rotor, delay_s=tuple(d + params["extra_delay_s"] for d in spec.rotor.delay_s)))
    if "wind" in vary:
        params["wind_mps"] = float(rng.uniform(0.0, VARY["wind"]))
    params["run_seed"] = int(rng.integers(2**31))
    return spec, params


def run_sample(task: dict) -> dict:
    """One Monte Carlo run (picklable task): flat metrics plus the drawn parameters."""
    from rotorlab.pipeline.stages.report import flatten_metrics
    from rotorlab.sim.runner import run_scenario

    spec, params = draw(task["vehicle"], task["vary"], task["seed_seq"])
    opts = {}
    if "wind_mps" in params and task["scenario"] in WIND_OPTION:
        opts[WIND_OPTION[task["scenario"]]] = params["wind_mps"]
    try:
        r = run_scenario(task["scenario"], spec, gains=task["gains"], seed=params["run_seed"],
                         duration_s=task["duration_s"], options=opts)
        row = {**flatten_metrics(r.metrics), "stopped": r.stopped or ""}
    except Exception as exc:  # a diverging or refused sample is a result, not a crash
        row = {"stopped": f"{type(exc).__name__}: {exc}"}
    return {"sample": task["i"], **params, **row}


def run(args) -> int:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from rotorlab import atomic
    from rotorlab.cli import CLIError
    from rotorlab.errors import RotorlabError
    from rotorlab.executor import get_executor
    from rotorlab.sim import scenarios
    from rotorlab.sim.runner import resolve_gains
    from rotorlab.vehicles import load_vehicle

    vary = [v.strip() for v in args.vary.split(",") if v.strip()]
    bad = [v for v in vary if v not in VARY]
    if bad:
        raise CLIError(f"--vary: unknown parameter '{bad[0]}'; valid: {', '.join(VARY)}")
    if args.n < 1 or args.batch < 1:
        raise CLIError("--n and --batch must be >= 1")
    try:
        scenarios.get(args.scenario)
        v = load_vehicle(args.vehicle)
        gains = resolve_gains(v, args.gains)
        ex = get_executor(args.executor, args.workers)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    out = Path(args.out or f"runs/montecarlo-{args.scenario}-{v.name}-seed{args.seed}")
    children = np.random.SeedSequence(args.seed).spawn(args.n)
    rows = []
    with ex:
        for b0 in range(0, args.n, args.batch):
            tasks = [{"i": i, "scenario": args.scenario, "vehicle": v, "vary": vary, "seed_seq": children[i],
                      "gains": gains, "duration_s": args.duration} for i in range(b0, min(args.n, b0 + args.batch))]
            batch = ex.map(run_sample, tasks, desc=f"runs {b0}-{b0 + len(tasks) - 1}", progress=True)
            keys = sorted(set().union(*batch))
            tbl = pa.table({k: [r.get(k) for r in batch] for k in keys})
            with atomic.atomic_path(out / f"batch-{b0 // args.batch:04d}.parquet") as tmp:
                pq.write_table(tbl, tmp)
            rows += batch
    summary = {"scenario": args.scenario, "vehicle": v.name, "gains": gains.name, "n": args.n, "seed": args.seed,
               "vary": {k: VARY[k] for k in vary},
               "fraction_stopped": float(np.mean([bool(r["stopped"]) for r in rows])),
               "metrics": {}}
    for k in sorted(set().union(*rows)):
        vals = np.array([r[k] for r in rows if isinstance(r.get(k), float)], float)
        if vals.size:
            q = np.quantile(vals, [0.05, 0.5, 0.95])
            summary["metrics"][k] = {"mean": float(vals.mean()), "std": float(vals.std()), "p05": float(q[0]),
                                     "p50": float(q[1]), "p95": float(q[2]), "n": int(vals.size)}
    atomic.write_json(out / "summary.json", summary)
    print(f"{args.n} runs of {args.scenario} -> {out} (stopped early: {summary['fraction_stopped']:.1%})")
    return 0
