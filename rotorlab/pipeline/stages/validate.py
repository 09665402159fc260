"""Stage 5, validate: every gain set (shipped and tuned) re-injected into the twin's validation scenarios,
with common random numbers (every set sees the same noise, gusts and turbulence)."""

from __future__ import annotations

from rotorlab.executor import task_seeds
from rotorlab.gains import parse_gains
from rotorlab.pipeline.models import gains_table
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable, write_log
from rotorlab.sim import scenarios
from rotorlab.sim.runner import run_scenario

__all__ = ["STAGE", "VALIDATION_SCENARIOS", "run_validation"]

VALIDATION_SCENARIOS = ("setpoint", "gust", "rope-pull", "hover")
SEED_OFFSET = 1  # validation seeds are children of seed + 1: independent of the campaign's


def run_validation(task: dict) -> dict:
    """One validation scenario with one gain set (picklable task). Returns metrics and the log arrays."""
    if task["scenario"] not in scenarios.SCENARIOS:
        return {"skipped": f"skipped: scenario '{task['scenario']}' is not registered in rotorlab.sim.scenarios"}
    gs = parse_gains(task["gains"], name=task["set"])
    opts = dict(task.get("options") or {})
    if task["scenario"] == "hover" and task.get("standard") is not None:
        # the published flight test: standard gains, switched in flight to the set under test (none for standard)
        if task["set"] == "standard":
            opts["switch_s"] = None
        else:
            opts["switch_to"] = gs
            gs = parse_gains(task["standard"], name="standard")
    try:
        r = run_scenario(task["scenario"], task["vehicle"], gains=gs, seed=task["seed"],
                         duration_s=task.get("duration_s"), options=opts)
    except Exception as exc:  # a scenario refusing this vehicle is reported, not fatal
        return {"skipped": f"skipped: {type(exc).__name__}: {exc}"}
    return {"metrics": jsonable(r.metrics), "stopped": r.stopped, "scene": r.info.get("scene"),
            "columns": {k: r.log[k].copy() for k in r.log.columns}, "units": r.log.units}


def run(ctx: StageContext) -> dict:
    sets = ctx.run.gain_sets()
    seeds = task_seeds(ctx.seed + SEED_OFFSET, len(VALIDATION_SCENARIOS))
    tasks = []
    for sc, seed in zip(VALIDATION_SCENARIOS, seeds):
        for name, gs in sets.items():
            # common random numbers: every gain set sees the same noise, gusts and turbulence
            tasks.append({"scenario": sc, "set": name, "vehicle": ctx.vehicle, "seed": seed,
                          "gains": gains_table(gs), "duration_s": ctx.settings["validation_s"].get(sc),
                          "options": {}, "standard": gains_table(sets["standard"]) if "standard" in sets else None})
    results = ctx.executor.map(run_validation, tasks, desc="validation", progress=ctx.opts.progress)
    (ctx.work / "logs").mkdir()
    res = {"validation": {}, "skipped": {}}
    for t, r in zip(tasks, results):
        if "skipped" in r:
            res["skipped"].setdefault(t["scenario"], r["skipped"])
            continue
        res["validation"].setdefault(t["scenario"], {})[t["set"]] = {**r["metrics"], "stopped": r["stopped"]}
        write_log(ctx.work / "logs" / f"{t['scenario']}__{t['set']}.parquet", r["columns"], r["units"],
                  {"scenario": t["scenario"], "gains": t["set"], "seed": t["seed"], "scene": r["scene"]})
    return res


STAGE = Stage("validate", upstream=("tune",), settings=("validation_s",), run=run)
