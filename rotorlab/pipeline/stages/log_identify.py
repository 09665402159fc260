"""Log stage 1, identify: read the flight log and identify its three axes (:func:`rotorlab.ident.flightlogs.run.
identify_flight_log`): per axis the closed loop (rate set-point -> rate), the plant (rate-loop output -> rate) where
the log has it, and the plant through the autopilot's known rate controller (the log's parameters). Writes
``models/<axis>[-<kind>].json`` and the identification report (``models/report.html``) and keeps the log's
parameters (``log.params``, the names of older firmware mapped onto the current laws'). With ``--vehicle`` the
plant structures carry that vehicle's IMU mount (``[imu] mount_frequency_hz``, ``mount_damping_ratio``)."""

from __future__ import annotations

from rotorlab import autopilots
from rotorlab.ident.flightlogs.plant_structures import file_plant
from rotorlab.ident.flightlogs.run import controller_params, identify_flight_log
from rotorlab.ident.modelio import load_model
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable
from rotorlab.tune.autopilot import px4_autotune_settings
from rotorlab.vehicles import load_vehicle

__all__ = ["STAGE", "plant_of", "usable_plant", "MIN_PLANT_VAF_PCT", "ANGLE_CONSISTENCY_POINTS", "MAX_GAIN_SPREAD",
           "ANGLE_ROUTE_AXES"]

#: a plant model is calibrated to and tuned on only where it predicts the held-out flight: at least this VAF (%)
#: and at least half the closed-loop model's (what the set-point -> rate data allows at all). The plant through
#: the controller is scored closed again with it (set-point -> rate, comparable with the closed-loop model), the
#: direct plant open loop. An axis without one keeps its inertia in the twin and the log's gains.
MIN_PLANT_VAF_PCT = 30.0
#: In an angle mode (the logged rate set-point is the angle loop's output) the attitude set-point is the input, and
#: the direct model from it (closed-loop-angle) is the most any model predicts from it (pilot-flown in wind: about
#: 30 % on the ArduCopter development log). The plant through the angle and rate controllers is then used where it
#: predicts within this many VAF points of that model (it explains what the input explains: issue 27's bar) ...
ANGLE_CONSISTENCY_POINTS = 5.0
#: ... and its gain, which sets the loop gain a tuning works with, is determined: the 95 % interval's half-width at
#: most this fraction of the estimate (a log of the rate loop at 24 Hz does not split the motor lag from the delay,
#: their sum it does)
MAX_GAIN_SPREAD = 0.25
#: the axes whose plant through the angle loop has the right structure (the rigid body's rate and its integral)
ANGLE_ROUTE_AXES = ("roll", "pitch")


def usable_plant(axis_models: dict, axis: str | None = None) -> tuple[str | None, str]:
    """The plant model of an axis to calibrate to and tune on (``"plant-indirect"``, ``"plant"``,
    ``"plant-indirect-angle"`` or None) and, when none, why (:data:`MIN_PLANT_VAF_PCT`; for the plant through the
    angle loop :data:`ANGLE_CONSISTENCY_POINTS` and :data:`MAX_GAIN_SPREAD`).

    Parameters
    ----------
    axis_models : dict
        Kind -> ``{"vaf_holdout_pct": ...}`` of one axis, with ``"closed-loop"``; a plant through the angle loop
        with ``"params"`` and ``"ci95"`` (its gain ``K``).
    axis : str, optional
        The plant through the angle loop is considered on :data:`ANGLE_ROUTE_AXES` only.

    Returns
    -------
    kind : str or None
    why : str
        Empty when a plant is usable.

    Examples
    --------
    >>> usable_plant({"closed-loop": {"vaf_holdout_pct": 56.2}, "plant-indirect": {"vaf_holdout_pct": 38.5}})
    ('plant-indirect', '')
    >>> usable_plant({"closed-loop": {"vaf_holdout_pct": 59.3}, "plant-indirect": {"vaf_holdout_pct": 12.4}})[0] is None
    True
    >>> angle = {"closed-loop-angle": {"vaf_holdout_pct": 28.7}, "plant-indirect-angle": {"vaf_holdout_pct": 28.1,
    ...          "params": {"K": 205.0}, "ci95": {"K": [168.9, 241.1]}}}
    >>> usable_plant({"closed-loop": {"vaf_holdout_pct": 59.3}, "plant-indirect": {"vaf_holdout_pct": 12.4}, **angle},
    ...              "roll")
    ('plant-indirect-angle', '')
    """
    cl = axis_models["closed-loop"]["vaf_holdout_pct"]
    floor = max(MIN_PLANT_VAF_PCT, 0.5 * cl)
    tried = []
    for kind in ("plant-indirect", "plant"):
        m = axis_models.get(kind)
        if m is None:
            continue
        if m["vaf_holdout_pct"] >= floor:
            return kind, ""
        tried.append(f"{kind} {m['vaf_holdout_pct']:.1f} %")
    why = (f"no plant model predicts the held-out flight well enough to tune on ({', '.join(tried) or 'none'}"
           f"; needed {floor:.1f} %: at least {MIN_PLANT_VAF_PCT:g} % and half the closed loop's {cl:.1f} %)")
    m, direct = axis_models.get("plant-indirect-angle"), axis_models.get("closed-loop-angle")
    if m is not None and direct is not None and axis in ANGLE_ROUTE_AXES:
        need = direct["vaf_holdout_pct"] - ANGLE_CONSISTENCY_POINTS
        k, (lo, hi) = m["params"]["K"], m["ci95"]["K"]
        spread = 0.5 * (hi - lo) / abs(k)
        if m["vaf_holdout_pct"] >= need and spread <= MAX_GAIN_SPREAD:
            return "plant-indirect-angle", ""
        why += (f"; through the angle loop {m['vaf_holdout_pct']:.1f} % against the direct model's "
                f"{direct['vaf_holdout_pct']:.1f} % (needed {need:.1f} %), its gain +-{100 * spread:.0f} % "
                f"(needed at most {100 * MAX_GAIN_SPREAD:.0f} %)")
    return None, why + ": the twin keeps its inertia and the axis its log gains"


def plant_of(path) -> tuple | None:
    """The plant of a model file written by this stage as ``(G, delay_s)``, normalised torque -> rad/s; None for
    a closed-loop model (the axis had no plant). The plant through the known controller is its axis's grey-box
    structure (:mod:`rotorlab.ident.flightlogs.plant_structures`) with its transport delay, without the autopilot's
    gyro low-pass the fit saw it through: taken continuous from its fitted parameters, so a delay that is not a whole number
    of log samples stays exact (its discrete form holds it as a state at z = 0, which has no continuous twin)."""
    G, delay_s, meta = load_model(path, whole_samples=False)
    units = meta.get("units") or {}
    if units.get((meta.get("input") or [""])[0]) != "1" or units.get((meta.get("output") or [""])[0]) != "rad/s":
        return None
    # the structure's own continuous plant, without the autopilot's gyro filter (the twin's gyro is the raw one)
    return file_plant(G, delay_s, meta)


def run(ctx: StageContext) -> dict:
    opts = ctx.opts
    # the IMU's mount is the user's vehicle's (--vehicle), not the generic start's: a flight log does not determine
    # it, and where the gyro filter passes it the plant models miss it without (identify_flight_log)
    imu = load_vehicle(opts.vehicle_file).imu if opts.vehicle_file else None
    res = identify_flight_log(opts.log, ctx.work / "models", holdout=ctx.settings["holdout"],
                              imu_mount=(imu.mount_frequency_hz, imu.mount_damping_ratio) if imu else None)
    log = res.log
    params, mapped = controller_params(log)
    autopilot = opts.autopilot or log.autopilot
    ap = autopilots.get(autopilot)
    # the log's parameters completed by the autopilot's defaults (a log of another autopilot: its defaults alone)
    given = {k: float(v) for k, v in params.items() if k in ap.TABLE} if autopilot == log.autopilot else {}
    current = ap.TABLE.complete(given, fill_defaults=True, source=str(opts.log))
    # PX4 autotune's own settings in the log (MC_AT_RISE_TIME, ...): the tune stage's autotune baseline flies them
    autotune = px4_autotune_settings(params, str(opts.log)) if autopilot == log.autopilot == "px4" else {}
    axes, notes = {}, []
    for axis, models in res.models.items():
        axes[axis] = {kind: {"vaf_holdout_pct": m.vaf_holdout, "method": m.model.method, "dt_s": m.dt,
                             "input": m.input, "output": m.output,
                             "holdout": [[w.start_s, w.stop_s] for w in m.split.holdout],
                             "ident": [[w.start_s, w.stop_s] for w in m.split.ident],
                             **{k: m.extra[k] for k in ("params", "ci95", "angle_p", "ff") if k in m.extra}}
                      for kind, m in models.items()}
        axes[axis]["use"], why = usable_plant(axes[axis], axis)
        if why:
            notes.append(f"{axis}: {why}")
    return jsonable({"log": str(log.path), "format": log.format, "log_autopilot": log.autopilot,
                     "version": log.version, "autopilot": autopilot, "loop_hz": ap.loop_hz(current),
                     "airborne_s": log.airborne_time_s(), "airborne_source": log.airborne_source,
                     "axes": axes, "log_params": current, "autotune_settings": autotune,
                     "log_params_defaulted": sorted(k for k in current if k not in given),
                     "mapped": [m.text() for m in mapped], "notes": list(log.notes) + list(res.notes) + notes})


STAGE = Stage("identify", upstream=(), settings=("holdout",), run=run)
