"""Log stage 3, tune: the autopilot's own attitude and rate loops tuned on the identified plants, axis by axis on
the executor (:func:`rotorlab.tune.autopilot.tune_axis`), against the generic multirotor spec the plants and the
baselines give (:func:`rotorlab.tune.autopilot_spec.generic_spec`; baselines: the log's parameters, the autopilot's
defaults and, for PX4, what PX4's autotune rule gives on the same plants), as ``rotorlab tune --autopilot`` does.

Writes ``spec.toml`` (the generated spec, every number's derivation in comments) and the parameter file
``tuned.params`` (PX4, QGroundControl) or ``tuned.parm`` (ArduPilot, Mission Planner): only the tuned gains, the
goals in its header. A set that misses a hard goal is written as ``tuned.failed.*`` with "do not fly" in its header.
The result holds each set's linear analysis per axis (margins, disturbance peak, gyro-noise gain).
"""

from __future__ import annotations

import tomllib

from rotorlab import autopilots
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable
from rotorlab.pipeline.stages.log_identify import plant_of
from rotorlab.tune import autopilot as T
from rotorlab.tune.autopilot_spec import generic_spec
from rotorlab.tune.spec import parse_spec

__all__ = ["STAGE", "tune_task", "load_plants"]


def load_plants(models_dir, use: dict, dt_s: float) -> dict:
    """axis -> ``(Gp, G, delay_s)``: the loop plant at ``dt_s`` (:func:`rotorlab.tune.autopilot.axis_plant`), the
    identified plant (normalised torque -> rad/s) and its delay, for every axis of ``use`` (axis -> the plant
    model's kind, None: no usable plant, left out)."""
    out = {}
    for axis, kind in use.items():
        if kind is not None:
            G, delay_s = plant_of(models_dir / f"{axis}-{kind}.json")
            out[axis] = (T.axis_plant(G, delay_s, dt_s), G, delay_s)
    return out


def tune_task(task: dict) -> dict:
    """One axis (picklable task): the tuned gains, every goal's value, the objective and the time."""
    spec = parse_spec(tomllib.loads(task["spec"]), name="generic", src="<generated spec>")
    r = T.tune_axis(spec.autopilot, task["params"], task["axis"], task["plant"], spec.goals[task["axis"]],
                    starts=task["starts"], seed=task["seed"], max_iter=task["max_iter"])
    return {"axis": r.axis, "gains": r.gains, "objective": r.objective, "time_s": r.time_s, "passed": r.passed,
            "goals": [{"goal": x.goal, "value": x.value, "hard": x.hard, "passed": x.passed} for x in r.report]}


def _analysis(ap, params, axis, Gp) -> dict:
    a = T.analyse_axis(ap, params, axis, Gp)
    return {"stable": a.stable, "dist_peak_rad": a.dist_peak_rad, "dist_iae_rad_s": a.dist_iae_rad_s,
            "disk_alpha": a.disk_alpha, "gm_db": a.gm_db, "pm_deg": a.pm_deg, "wc_rad_s": list(a.wc_rad_s),
            "noise_gain": a.noise_gain}


def run(ctx: StageContext) -> dict:
    ident = ctx.run.result("identify")
    ap = autopilots.get(ident["autopilot"])
    current = dict(ident["log_params"])
    dt_s = 1.0 / ap.loop_hz(current)
    plants = load_plants(ctx.run.stage_dir("identify") / "models", {a: m["use"] for a, m in ident["axes"].items()},
                         dt_s)
    if not plants:
        return {"skipped": "no axis has a plant model to tune on", "autopilot": ap.NAME}
    baselines, rejected = T.baseline_sets(ap, {a: p[0] for a, p in plants.items()}, current, "log",
                                          ident.get("autotune_settings"))
    spec_text = generic_spec(ap, plants, dt_s, current, baselines, model=f"the flight log {ident['log']}")
    (ctx.work / "spec.toml").write_text(spec_text, encoding="utf-8")
    s = ctx.settings
    tasks = [{"spec": spec_text, "params": current, "axis": a, "plant": p[0], "starts": s["tune_starts"],
              "seed": ctx.seed, "max_iter": s["tune_max_iter"]} for a, p in plants.items()]
    results = {r["axis"]: r for r in ctx.executor.map(tune_task, tasks, desc="tuning", progress=ctx.opts.progress)}
    tuned = T.tuned_parameters(ap, {a: r["gains"] for a, r in results.items()})
    failed = [f"{a} {g['goal']}" for a, r in results.items() for g in r["goals"] if g["hard"] and not g["passed"]]
    header = [f"rotorlab pipeline --log {ident['log']}: {', '.join(results)} tuned at {1 / dt_s:g} Hz on the "
              "identified plants (generic multirotor spec: crossover band, disk margin floor, gyro-noise bound hard; "
              "input-disturbance peak and low-frequency rejection soft)"]
    for a, r in results.items():
        header.append(f"{a}: " + "; ".join(f"{g['goal']} {g['value']:.3f}" + (" (hard)" if g["hard"] else " (soft)")
                                           for g in r["goals"]))
    suffix = ".params" if ap.FILE_FORMAT == "qgc" else ".parm"
    name = "tuned" + (".failed" if failed else "") + suffix
    autopilots.write_params(ap.NAME, ctx.work / name, tuned, header=T.parameter_file_header(header, failed))
    sets = {"log": current, "tuned": {**current, **tuned}, **{k: v for k, v in baselines.items() if k != "log"}}
    analysis = {name_: {a: _analysis(ap, p, a, plants[a][0]) for a in plants} for name_, p in sets.items()}
    return jsonable({"autopilot": ap.NAME, "loop_hz": 1 / dt_s, "axes": list(results), "tuned": tuned,
                     "params_file": name, "failed": failed, "results": results, "analysis": analysis,
                     "px4_autotune_rejected": rejected,
                     "delay_s": {a: p[2] for a, p in plants.items()}})


STAGE = Stage("tune", upstream=("identify",), settings=("tune_starts", "tune_max_iter"), run=run)
