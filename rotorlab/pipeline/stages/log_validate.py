"""Log stage 4, validate: the log's parameters and the tuned set re-injected into the calibrated twin.

Per axis on the calibrated twin's exact linearisation (gimbal scene: rotation about the CG; motors and delay in;
:func:`rotorlab.pipeline.stages.log_calibrate.twin_plant`) closed by the autopilot's law at its loop rate
(:func:`rotorlab.autopilots.closed_loop_lti`): a rate step (the acro mode), an angle step (attitude mode) and a
input-disturbance step of :data:`DIST_STEP` (normalised torque at the plant input,
:func:`rotorlab.tune.autopilot.disturbance_response`). The step sizes are linear-range (the metrics scale with them; saturation is the
simulations' part). In the twin itself (MuJoCo, the autopilot's stateful laws flown by the flight software with
common random numbers, every set seeing the same gusts and turbulence, seeds children of ``seed + 1``): a 1-cosine
gust from ahead (pitch) and from the side (roll), and hover in Dryden turbulence, whose motor-command
high-frequency power is the motor-command noise the report leads with. A scenario the twin refuses is reported as
skipped.
"""

from __future__ import annotations

import math

import numpy as np

from rotorlab import autopilots, lti
from rotorlab.executor import task_seeds
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable, write_log
from rotorlab.pipeline.stages.log_calibrate import twin_plant_continuous
from rotorlab.sim.control.autopilot import AutopilotSpec
from rotorlab.sim.runner import run_scenario
from rotorlab.stepresponse import step_metrics
from rotorlab.tune import autopilot as T
from rotorlab.vehicles import load_vehicle

__all__ = ["STAGE", "TWIN_SCENARIOS", "SETS", "linear_axis", "run_twin"]

SETS = ("log", "tuned")
#: the twin's scenarios: key -> (scenario, options)
TWIN_SCENARIOS = {
    "gust-pitch": ("gust", {"from_deg": 0.0}),
    "gust-roll": ("gust", {"from_deg": 90.0}),
    "hover": ("hover", {"switch_s": "none"}),
}
RATE_STEP_RAD_S = math.radians(30.0)
DIST_STEP = 0.1  # input-disturbance step, normalised torque: a tenth of the full differential command
ANGLE_STEP_RAD = math.radians(5.0)
HORIZON_S = 2.0


def _axis_plants(v, axis: str, dt_s: float) -> dict:
    """The twin's plants of ``axis`` at the loop period, normalised torque in: ``"rate"`` (rad/s) and
    ``"attitude"`` (``[rate, angle]``, rad/s and rad), each with the rotors' transport delay."""
    Gc, delay_s = twin_plant_continuous(v, axis)
    # the rate loop on the rate alone: the angle is an open integrator there, not a closed-loop pole
    return {"rate": lti.c2d_zoh_delay(Gc, dt_s, delay_s), "attitude": T.axis_plant(Gc, delay_s, dt_s)}


def _step(T_cl, size: float, dt_s: float) -> dict:
    n = int(round(HORIZON_S / dt_s))
    t = np.arange(n) * dt_s
    A, B, C, D = (np.asarray(M, float) for M in (T_cl.A, T_cl.B, T_cl.C, T_cl.D))
    x = np.zeros(A.shape[0])
    y = np.empty((n, C.shape[0]))
    for k in range(n):
        y[k] = C @ x + D[:, 0] * size
        x = A @ x + B[:, 0] * size
    return t, y


def linear_axis(autopilot: str, params: dict, axis: str, plants: dict) -> dict:
    """Rate step, angle step and input-disturbance step of one axis on ``plants`` (:func:`_axis_plants`), with the
    command's peak per unit of step."""
    Gp = plants["attitude"]
    dt = float(Gp.dt)
    out = {}
    for loop, size in (("rate", RATE_STEP_RAD_S), ("attitude", ANGLE_STEP_RAD)):
        Tcl = autopilots.closed_loop_lti(autopilot, params, axis, plants[loop], loop=loop)
        if not lti.is_stable(Tcl):
            out[loop] = {"stable": False}
            continue
        t, y = _step(Tcl, size, dt)
        yl = y[:, 0 if loop == "rate" else 1]
        m = step_metrics(t, yl, size)
        # the tracking error's integral per unit of step (s): one figure for speed and overshoot together, where a
        # slow loop without overshoot and a fast one with a little are otherwise not comparable
        out[loop] = {"stable": True, "step": size, **m, "iae_per_step_s": float(np.sum(np.abs(1.0 - yl / size)) * dt),
                     "command_peak": float(np.max(np.abs(y[:, -1])))}
    if not out["attitude"]["stable"]:  # the disturbance acts on the same closed loop
        out["disturbance"] = {"stable": False}
        return out
    d = DIST_STEP * T.disturbance_response(autopilot, params, axis, Gp, HORIZON_S)
    out["disturbance"] = {"stable": True, "peak_rad": float(np.max(np.abs(d))),
                          "iae_rad_s": float(np.sum(np.abs(d)) * dt), "final_rad": float(d[-1])}
    return out


def run_twin(task: dict) -> dict:
    """One twin scenario with one parameter set (picklable task): metrics and the log's columns."""
    scenario, options = TWIN_SCENARIOS[task["key"]]
    spec = AutopilotSpec.from_params(task["autopilot"], task["params"], source=task["set"])
    try:
        r = run_scenario(scenario, task["vehicle"], scene="free-flight", seed=task["seed"],
                         duration_s=task["duration_s"], options=options, controller=spec)
    except Exception as exc:  # a scenario the twin refuses is reported, not fatal
        return {"skipped": f"skipped: {type(exc).__name__}: {exc}"}
    return {"metrics": jsonable(r.metrics), "stopped": r.stopped,
            "columns": {k: r.log[k].copy() for k in r.log.columns}, "units": r.log.units}


def run(ctx: StageContext) -> dict:
    cal = ctx.run.result("calibrate")
    tune = ctx.run.result("tune")
    ident = ctx.run.result("identify")
    if "skipped" in tune or "skipped" in cal:
        return {"skipped": f"nothing to validate: {tune.get('skipped') or cal.get('skipped')}"}
    ap = tune["autopilot"]
    sets = {"log": dict(ident["log_params"]), "tuned": {**ident["log_params"], **tune["tuned"]}}
    vehicle = str((ctx.run.stage_dir("calibrate") / cal["vehicle"]).resolve())  # every worker reads this file
    v = load_vehicle(vehicle)
    dt = 1.0 / float(tune["loop_hz"])
    linear = {}
    for axis in tune["axes"]:
        plants = _axis_plants(v, axis, dt)
        linear[axis] = {name: linear_axis(ap, p, axis, plants) for name, p in sets.items()}
    seeds = task_seeds(ctx.seed + 1, len(TWIN_SCENARIOS))
    dur = ctx.settings["validation_s"]
    tasks = [{"key": key, "set": name, "autopilot": ap, "params": p, "vehicle": vehicle, "seed": seed,
              "duration_s": dur.get(sc)} for (key, (sc, _)), seed in zip(TWIN_SCENARIOS.items(), seeds)
             for name, p in sets.items()]
    results = ctx.executor.map(run_twin, tasks, desc="twin scenarios", progress=ctx.opts.progress)
    (ctx.work / "logs").mkdir()
    twin, skipped = {}, {}
    for t, r in zip(tasks, results):
        if "skipped" in r:
            skipped.setdefault(t["key"], r["skipped"])
            continue
        twin.setdefault(t["key"], {})[t["set"]] = {**r["metrics"], "stopped": r["stopped"]}
        write_log(ctx.work / "logs" / f"{t['key']}__{t['set']}.parquet", r["columns"], r["units"],
                  {"scenario": TWIN_SCENARIOS[t["key"]][0], "set": t["set"], "seed": t["seed"],
                   "vehicle": "calibrated twin", "autopilot": ap})
    return jsonable({"linear": linear, "twin": twin, "twin_skipped": skipped, "sets": list(sets), "dist_step": DIST_STEP,
                     "rate_step_rad_s": RATE_STEP_RAD_S, "angle_step_rad": ANGLE_STEP_RAD})


STAGE = Stage("validate", upstream=("identify", "calibrate", "tune"), settings=("validation_s",), run=run)
