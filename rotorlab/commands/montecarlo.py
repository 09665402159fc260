"""Scenario Monte Carlo over seeded parameter spreads of the twin (mass, inertia, delay, wind).

Each sample i draws its parameters and its run seed from child i of SeedSequence(--seed), so the numbers do
not depend on the executor or the batch size. --vary takes NAME or NAME=SPREAD items, drawn as in the gym envs
and the batched runner (rotorlab.sim.randomize): the mass and each principal inertia are scaled by factors
uniform in [1 - SPREAD, 1 + SPREAD] (default 0.1), delay is a whole number of physics steps uniform in
[delay, delay + SPREAD] s (default 0.02 s), wind sets a mean wind uniform in [0, SPREAD] m/s (default 5; gust,
hover and prbs-flight only). Every drawn vehicle is physical: a mass/inertia draw whose airframe body would
break A + B >= C is redrawn, and a delay drawn above the vehicle file's bound (1 s) is redrawn within it; the
redraws are counted and reported apart from the flight outcomes. Writes one Parquet of metrics per batch
(batch-0000.parquet, ...) and summary.json (mean, std and 5/50/95 % quantiles of every metric, the fraction of
the flown runs that stopped early, the redrawn draws, the runs that failed to build or run, which are not flight
outcomes and make the exit status 1), and prints the statistics of the scenario's key metrics.
"""

from __future__ import annotations

import numpy as np

from rotorlab.cli import CLIError, bounded_int, describe, process_count, seed_int
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.

#: parameter -> default spread (distributions: rotorlab.sim.randomize; ``delay`` is its ``delay_s``)
VARY = {"mass": 0.10, "inertia": 0.10, "delay": 0.02, "wind": 5.0}
VARY_UNITS = {"mass": "relative", "inertia": "relative", "delay": "s", "wind": "m/s"}
WIND_OPTION = {"gust": "mean_wind_mps", "hover": "wind_mps", "prbs-flight": "wind_mps"}
#: units of the batch tables' sample columns besides the draw's (rotorlab.sim.randomize.DRAW_UNITS; a metric
#: column carries its unit in its name, e.g. rise_time_s)
SAMPLE_UNITS = {"sample": "1", "run_seed": "1"}
#: most runs of one Monte Carlo (each a simulation of seconds; every row is kept in memory for the summary)
MAX_RUNS = 100_000
#: largest mean wind drawn, m/s: a storm, beyond any multirotor's flight envelope
MAX_WIND_MPS = 50.0



def add_parser(sub):
    p = sub.add_parser("montecarlo", help="scenario Monte Carlo over seeded vehicle/wind parameter spreads",
                       **describe(__doc__))
    p.add_argument("scenario", help="scenario name (see rotorlab list)")
    p.add_argument("--vehicle", default="anteos-p2a2", help="vehicle name or vehicle TOML path")
    p.add_argument("--gains", default=None, help="gain set name or gains TOML (default: the vehicle's standard set)")
    p.add_argument("--n", type=bounded_int(MAX_RUNS), default=100, help=f"number of runs (at most {MAX_RUNS})")
    p.add_argument("--vary", default="mass,inertia,delay",
                   help="comma list of NAME or NAME=SPREAD, NAME from " +
                        ", ".join(f"{k} (spread {v:g} {VARY_UNITS[k]})" for k, v in VARY.items()))
    p.add_argument("--duration", type=float, default=None, help="run duration, s (default: the scenario's)")
    p.add_argument("--seed", type=seed_int, default=0, help="master seed of the parameter draws and the runs")
    p.add_argument("--batch", type=bounded_int(MAX_RUNS), default=50, help="runs per Parquet batch")
    p.add_argument("--executor", default="local", help="local (processes), serial, dask or dask://HOST:PORT (an "
                   "existing scheduler: connect only to one you trust, it sends pickled objects that run code "
                   "here; docs/security.md)")
    p.add_argument("--workers", type=process_count, default=None,
                   help="worker processes, at most twice the CPUs (default: the executor's choice)")
    p.add_argument("--out", default=None, help="output folder (default runs/montecarlo-SCENARIO-VEHICLE-seedN)")
    return p


def parse_vary(text: str) -> dict:
    """``"mass=0.2,delay"`` -> ``{"mass": 0.2, "delay": 0.02}`` (a bare name takes its default spread)."""
    out = {}
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        name, _, val = item.partition("=")
        name = name.strip()
        if name not in VARY:
            raise CLIError(f"--vary: unknown parameter '{name}'; expected one of {', '.join(VARY)} (as NAME or "
                           "NAME=SPREAD)")
        if not val:
            out[name] = VARY[name]
            continue
        try:
            spread = float(val)
        except ValueError:
            raise CLIError(f"--vary {name}: expected a number as the spread, got '{val}'") from None
        if not (spread >= 0 and np.isfinite(spread)) or (name in ("mass", "inertia") and spread >= 1):
            raise CLIError(f"--vary {name}: expected a spread >= 0" + (" and < 1 (a relative scale)"
                           if name in ("mass", "inertia") else "") + f", got {spread:g}")
        if name == "wind" and spread > MAX_WIND_MPS:
            raise CLIError(f"--vary wind: expected a spread of at most {MAX_WIND_MPS:g} m/s, got {spread:g}")
        out[name] = spread
    return out


def _check_delay_spread(vehicle, vary: dict) -> None:
    """The drawn delays stay within the vehicle file's documented range of ``rotor.delay_s``
    (:data:`rotorlab.vehicles.spec.MAX_LAG_DELAY_S`): --vary delay=5 drew 3.4-4.0 s delays the file caps at 1 s."""
    from rotorlab.vehicles.spec import MAX_LAG_DELAY_S

    if "delay" in vary:
        room = MAX_LAG_DELAY_S - max(vehicle.rotor.delay_s)
        if vary["delay"] > room + 1e-12:
            raise CLIError(f"--vary delay: expected a spread of at most {room:g} s (the vehicle's delay "
                           f"{max(vehicle.rotor.delay_s):g} s plus the spread must stay within rotor.delay_s's "
                           f"range [0, {MAX_LAG_DELAY_S:g}] s), got {vary['delay']:g}")


def draw(vehicle, vary: dict, seed_seq):
    """Varied vehicle spec and drawn parameters (with the run seed) of one sample; ``vary`` maps a parameter to
    its spread. The draw is :func:`rotorlab.sim.randomize.draw`, the one the envs and the batched runner use."""
    from rotorlab.scenes import PHYSICS_DT_S
    from rotorlab.sim import randomize

    rng = np.random.default_rng(seed_seq)
    spreads = {("delay_s" if k == "delay" else k): v for k, v in vary.items()}
    d = randomize.draw(vehicle, spreads, rng, PHYSICS_DT_S, field="--vary")
    params = {k: v for k, v in d.as_dict().items() if k != "wind_from_deg"}  # the scenario sets the direction
    params["run_seed"] = int(rng.integers(2**31))
    return randomize.apply(vehicle, d), params


def run_sample(task: dict) -> dict:
    """One Monte Carlo run (picklable task): flat metrics plus the drawn parameters."""
    from rotorlab.keymetrics import flatten_metrics
    from rotorlab.sim.runner import run_scenario

    spec, params = draw(task["vehicle"], task["vary"], task["seed_seq"])
    opts = {}
    if "wind" in task["vary"] and task["scenario"] in WIND_OPTION:
        opts[WIND_OPTION[task["scenario"]]] = params["wind_speed_mps"]
    try:
        r = run_scenario(task["scenario"], spec, gains=task["gains"], seed=params["run_seed"],
                         duration_s=task["duration_s"], options=opts)
        row = {**flatten_metrics(r.metrics), "stopped": r.stopped or "", "error": ""}
    except Exception as exc:  # a sample that could not be built or flown is reported, apart from flight outcomes
        row = {"stopped": "", "error": f"{type(exc).__name__}: {exc}"}
    return {"sample": task["i"], **params, **row}


def run(args) -> int:
    import pyarrow as pa

    from rotorlab import atomic
    from rotorlab.executor import get_executor
    from rotorlab.logformat import write_parquet
    from rotorlab.sim import randomize, scenarios
    from rotorlab.sim.runner import check_duration, resolve_gains
    from rotorlab.vehicles import load_vehicle

    vary = parse_vary(args.vary)
    if args.n < 1 or args.batch < 1:
        raise CLIError("--n and --batch must be >= 1")
    try:
        scenarios.get(args.scenario)
        v = load_vehicle(args.vehicle)
        _check_delay_spread(v, vary)
        if args.duration is not None:  # before any run: every sample would fail alike in its worker
            check_duration(args.duration, v.control_dt_s)
        gains = resolve_gains(v, args.gains)
        draw(v, vary, np.random.SeedSequence(args.seed))  # spreads no vehicle can take: refused before any run
        out = atomic.check_output(args.out or f"runs/montecarlo-{args.scenario}-{v.name}-seed{args.seed}",
                                  flag="--out", what="folder")
        ex = get_executor(args.executor, args.workers)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    children = np.random.SeedSequence(args.seed).spawn(args.n)
    rows = []
    with ex:
        for b0 in range(0, args.n, args.batch):
            tasks = [{"i": i, "scenario": args.scenario, "vehicle": v, "vary": vary, "seed_seq": children[i],
                      "gains": gains, "duration_s": args.duration} for i in range(b0, min(args.n, b0 + args.batch))]
            batch = ex.map(run_sample, tasks, desc=f"runs {b0}-{b0 + len(tasks) - 1}", progress=True)
            keys = sorted(set().union(*batch))
            tbl = pa.table({k: [r.get(k) for r in batch] for k in keys})
            write_parquet(out / f"batch-{b0 // args.batch:04d}.parquet", tbl,
                          {k: u for k, u in {**SAMPLE_UNITS, **randomize.DRAW_UNITS}.items() if k in keys},
                          {"scenario": args.scenario, "vehicle": v.name, "gains": gains.name, "seed": args.seed})
            rows += batch
    flown = [r for r in rows if not r["error"]]
    errors = [r for r in rows if r["error"]]
    summary = {"scenario": args.scenario, "vehicle": v.name, "gains": gains.name, "n": args.n, "seed": args.seed,
               "vary": vary,
               "fraction_stopped": float(np.mean([bool(r["stopped"]) for r in flown])) if flown else None,
               "n_flown": len(flown),
               "errors": {"n": len(errors), "first": errors[0]["error"] if errors else None},
               "redrawn": {"bodies_samples": sum(r.get("rejected_bodies", 0) > 0 for r in rows),
                           "bodies_candidates": sum(r.get("rejected_bodies", 0) for r in rows),
                           "delay_samples": sum(r.get("rejected_delay", 0) for r in rows)},
               "metrics": {}}
    for k in sorted(set().union(*rows)):
        vals = np.array([r[k] for r in rows if isinstance(r.get(k), float)], float)
        if vals.size:
            q = np.quantile(vals, [0.05, 0.5, 0.95])
            summary["metrics"][k] = {"mean": float(vals.mean()), "std": float(vals.std()), "p05": float(q[0]),
                                     "p50": float(q[1]), "p95": float(q[2]), "n": int(vals.size)}
    atomic.write_json(out / "summary.json", summary)
    print("\n".join(statistics_lines(summary)))
    print(f"wrote {out} (summary.json, batch-*.parquet)")
    return 1 if errors else 0


def statistics_lines(summary: dict, max_rows: int = 12) -> list[str]:
    """The Monte Carlo statistics of the scenario's key metrics, one line each with its unit."""
    from rotorlab.keymetrics import fmt, key_rows, lookup
    from rotorlab.vehicles.spec import MAX_LAG_DELAY_S

    vary = ", ".join(f"{k} {v:g} {VARY_UNITS[k]}" for k, v in summary["vary"].items()) or "nothing"
    n_flown = summary.get("n_flown", summary["n"])
    L = [f"{summary['n']} runs of {summary['scenario']} on {summary['vehicle']}, gains {summary['gains']}, "
         f"seed {summary['seed']}; varied: {vary}; stopped early: "
         + (f"{100 * summary['fraction_stopped']:.1f} % of {n_flown} flown" if n_flown else "none flown")]
    red = summary.get("redrawn", {})
    if red.get("bodies_samples") or red.get("delay_samples"):
        L.append(f"  draws kept physical: {red['bodies_samples']} sample(s) redrew mass/inertia "
                 f"({red['bodies_candidates']} candidate(s) without a rigid airframe body), "
                 f"{red['delay_samples']} redrew a delay above {MAX_LAG_DELAY_S:g} s (the vehicle file's bound)")
    err = summary.get("errors", {})
    if err.get("n"):
        L.append(f"  {err['n']} run(s) failed before or outside the flight and are not in the statistics; "
                 f"first: {err['first']}")
    stats = summary["metrics"]
    means = {k: v["mean"] for k, v in stats.items()}
    rows = key_rows(summary["scenario"], means, rest=False) or key_rows(summary["scenario"], means)[:max_rows]
    if not rows:
        return L + ["no metric was scored (every run stopped early?)"]
    w = max(len(f"{label} [{unit}]") for _, label, unit, _ in rows)
    L.append(f"  {'metric':<{w}}  {'mean':>9} {'std':>9} {'p05':>9} {'p50':>9} {'p95':>9}")
    for key, label, unit, _ in rows[:max_rows]:
        st = lookup(stats, key)
        name = f"{label} [{unit}]" if unit else label
        L.append(f"  {name:<{w}}  " + " ".join(f"{fmt(st[q]):>9}" for q in ("mean", "std", "p05", "p50", "p95")))
    return L
