"""Log stage 2, calibrate: the twin's inertia, motor poles and delays fitted to the identified per-axis plants
(:func:`rotorlab.vehicles.fit_axes.calibrate_axes_staged`), and the calibrated twin's prediction of the held-out flight.

The starting twin is ``--vehicle`` (a vehicle TOML, e.g. from ``rotorlab vehicle new``, or a shipped name), else
the shipped ``x500`` (PX4's reference vehicle). A log's plant runs from the autopilot's normalised torque to rad/s;
the twin's from its axis command (%) to deg/s, with a normalised torque of 1 a differential command of 100 %
(:data:`rotorlab.sim.control.autopilot.TORQUE_TO_PCT`); the target is converted accordingly. PX4's allocator and
ArduPilot's mixer scale the torque by the airframe's geometry, which the twin does not model, so the torque gain
per inertia the log shows can be far from the starting twin's: where an axis's gain at :data:`W_START_RAD_S`
differs by more than :data:`MAX_START_RATIO`, that axis's inertia is first scaled to match it (the fit's inertia
range is a factor of 3 around its start), and the report says so.

The check of the calibration against the flight: per axis, the calibrated twin's linearisation (gimbal scene) is
closed with the log's own rate controller exactly as the identification closes its plant through the controller
(:func:`rotorlab.ident.flightlogs.identify.identify_plant_indirect`), driven by the logged rate set-point, and its
free-run VAF on the held-out windows is compared with the closed-loop model's (the ARX-family fit of the
set-point -> rate data).
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.ident.flightlogs import read_flight_log
from rotorlab.ident.flightlogs.identify import angle_cascade, controller_at, holdout_prediction, loop_substeps
from rotorlab.ident.flightlogs.run import angle_record, autopilot_controller, autopilot_gyro_filter
from rotorlab.ident.flightlogs.windows import Window
from rotorlab.ident.greybox import _closed_loop, lift_interpolated
from rotorlab.ident.model import IdentifiedModel
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable
from rotorlab.pipeline.stages.log_identify import plant_of
from rotorlab.scenes import PHYSICS_DT_S
from rotorlab.sim.control.autopilot import TORQUE_TO_PCT
from rotorlab.sim.linearize import linearize
from rotorlab.tune.autopilot import axis_plant
from rotorlab.vehicles import load_vehicle, vehicle_path
from rotorlab.vehicles.fit_axes import (
    AXES,
    DELAY_RANGE_S,
    INERTIA_INDEX,
    LAG_RANGE_S,
    axis_delay_s,
    calibrate_axes_staged,
    twin_response,
    twin_scene,
    write_calibrated,
)

__all__ = ["STAGE", "DEFAULT_VEHICLE", "twin_plant", "twin_plant_continuous", "target_model", "twin_holdout_vaf"]

DEFAULT_VEHICLE = "x500"
W_START_RAD_S = 1.0  # where the starting twin's gain is compared with the log's: the fit band's lower end, where the
# rate response is the integrator b / s alone (motor pole and delay do not count yet)
MAX_START_RATIO = 2.0  # well inside the fit's inertia range (a factor of 3 either way)
# the twin's per-axis linearisation carries every state of the airframe; the other axes' modes, neither driven nor
# seen, cancel to this tolerance (python-control's default keeps them in a yaw model: 12 states instead of 4)
MINREAL_TOL = 1e-6
_SCALE = TORQUE_TO_PCT * math.pi / 180.0  # (rad/s per normalised torque) / (deg/s per %)


def target_model(path):
    """The identified plant of a model file as a calibration target: axis command % -> deg/s, with its delay;
    None for a closed-loop model."""
    plant = plant_of(path)
    return None if plant is None else (plant[0] * (1.0 / _SCALE), plant[1])


def twin_plant_continuous(v, axis: str) -> tuple[ct.StateSpace, float]:
    """The twin's plant of ``axis`` (gimbal scene) from normalised torque to rad/s, continuous and without its
    delay, and the delay of the rotors that drive the axis, s (:func:`rotorlab.vehicles.fit_axes.axis_delay_s`)."""
    Gd = linearize(twin_scene(v, "gimbal"), v, axis, f"gyro_{axis}", delay=False)
    # the other axes' states are neither driven nor seen: their integrators would read as closed-loop poles at 1
    Gc = ct.minreal(lti.d2c_zoh(Gd), tol=MINREAL_TOL, verbose=False)
    return Gc * _SCALE, axis_delay_s(v, axis)


def twin_plant(v, axis: str, dt_s: float) -> ct.StateSpace:
    """The twin's plant of ``axis`` (gimbal scene) from normalised torque to rad/s, discrete at ``dt_s`` with the
    transport delay of the rotors that drive it (held input, :func:`rotorlab.lti.c2d_zoh_delay`)."""
    Gc, delay_s = twin_plant_continuous(v, axis)
    return lti.c2d_zoh_delay(Gc, dt_s, delay_s)


def twin_holdout_vaf(log, v, axis: str, dt_s: float, holdout, angle: tuple | None = None) -> float:
    """Free-run VAF (%) of the twin closed with the log's rate controller on the held-out windows, driven by the
    logged rate set-point; with ``angle = (angle_p, ff)`` closed with the angle and rate controllers
    (:func:`rotorlab.ident.flightlogs.identify.angle_cascade`) and driven by the attitude set-point, as the plant
    through the angle loop was fitted and scored."""
    C = autopilot_controller(log, axis)
    sub = loop_substeps(C, dt_s)
    Gc, delay_s = twin_plant_continuous(v, axis)
    if angle is None:
        rec = log.record(axis, ("rate_sp", "rate"), rate_hz=1.0 / dt_s)
        K, feedback, u_name = controller_at(C, rec.dt / sub), 0, "rate_sp"
        plant = lti.c2d_zoh_delay(Gc, rec.dt / sub, delay_s)
    else:
        rec = angle_record(log, axis, dt_s)
        K, feedback, u_name = angle_cascade(C, *angle, rec.dt / sub), (0, 1), "att_sp"
        plant = axis_plant(Gc, delay_s, rec.dt / sub)  # [rate, angle]: the attitude the rate integrated
    gyro_filter = autopilot_gyro_filter(log)
    if gyro_filter is not None:  # the controller and the log both see the rate through the autopilot's gyro filter
        F = gyro_filter(rec.dt / sub)
        plant = ct.series(plant, F if angle is None else ct.append(F, ct.ss([], [], [], [[1.0]], rec.dt / sub)))
    cl_fast = _closed_loop(plant, K, feedback)
    cl = IdentifiedModel(sys=lift_interpolated(cl_fast, sub)[0, :], method="twin-closed-loop",
                         settings={"substeps": sub})
    windows = [Window(float(a), float(b), "held out") for a, b in holdout]
    return holdout_prediction(cl, rec, u_name, "rate", windows)[0]


def _start_vehicle(opts):
    name = opts.vehicle_file or DEFAULT_VEHICLE
    return load_vehicle(name), vehicle_path(name)


def run(ctx: StageContext) -> dict:
    ident = ctx.run.result("identify")
    models = ctx.run.stage_dir("identify") / "models"
    v0, source = _start_vehicle(ctx.opts)
    notes, targets = [], {}
    for axis in AXES:
        a = ident["axes"].get(axis)
        if a is None:
            notes.append(f"{axis}: not identified in the log; the twin keeps its inertia")
            continue
        if a["use"] is None:  # the identify stage's notes say why
            continue
        targets[axis] = target_model(models / f"{axis}-{a['use']}.json")
    if not targets:
        return {"skipped": "no axis has a plant model to calibrate to", "notes": notes, "start_vehicle": str(source)}
    # the motor pole and delay start where the plants through the controller put them (the fit walks along the
    # lag-delay valley from a far start and can end at a bound: the S250 log went to 2 ms and 73 ms from x500's)
    grey = [ident["axes"][a][ident["axes"][a]["use"]]["params"] for a in targets
            if "params" in ident["axes"][a][ident["axes"][a]["use"]]]
    if grey:
        lag = float(np.clip(np.mean([g["tau_s"] for g in grey]), *LAG_RANGE_S))
        # in whole physics steps: MuJoCo realises the delay with its actuator history
        delay = round(float(np.clip(np.mean([g["delay_s"] for g in grey]), *DELAY_RANGE_S)) / PHYSICS_DT_S) * PHYSICS_DT_S
        v0 = dataclasses.replace(v0, rotor=dataclasses.replace(v0.rotor, lag_s=(lag,) * len(v0.rotor.lag_s),
                                                                  delay_s=(delay,) * len(v0.rotor.delay_s)))
        notes.append(f"fit started at the identified motor lag {lag * 1e3:.1f} ms and delay {delay * 1e3:.1f} ms")
    # the starting gain, axis by axis: far outside the fit's range, the inertia is moved to the log's first
    w0 = np.array([W_START_RAD_S])
    start = twin_response(v0, list(targets), w0)
    inertia = list(v0.inertia_kgm2)
    prescaled = {}
    for axis, (G, _) in targets.items():
        ratio = float(abs(start[axis][0]) / abs(lti.freqresp(G, w0)[0, 0, 0]))
        if not 1.0 / MAX_START_RATIO <= ratio <= MAX_START_RATIO:
            inertia[INERTIA_INDEX[axis]] *= ratio
            prescaled[axis] = ratio
    if prescaled:
        inertia = _physical(inertia, {INERTIA_INDEX[a] for a in targets})
        v0 = dataclasses.replace(v0, inertia_kgm2=tuple(inertia))
        notes.append("starting inertia scaled to the log's torque gain first ("
                     + ", ".join(f"{a} x{r:.3g}" for a, r in prescaled.items())
                     + "): the log's normalised torque is not the twin's (allocator scaling)")
    cal = calibrate_axes_staged(v0, targets)
    out = write_calibrated(source, cal, ctx.work / "vehicle.toml",
                           note=f"calibrated to the flight log {ident['log']} (rotorlab pipeline --log)")
    v = load_vehicle(str(out))
    log = read_flight_log(ctx.opts.log)
    prediction = {}
    for axis in targets:
        a = ident["axes"][axis]
        # the pair that shares the input of the plant used: the rate set-point, or in an angle mode the attitude's
        through_angle = a["use"] == "plant-indirect-angle"
        cl, ind = (a["closed-loop-angle"], a["plant-indirect-angle"]) if through_angle else \
            (a["closed-loop"], a.get("plant-indirect") or {})
        angle = (ind["angle_p"], ind["ff"]) if through_angle else None
        twin_vaf = twin_holdout_vaf(log, v, axis, cl["dt_s"], cl["holdout"], angle)
        prediction[axis] = {"twin_vaf_pct": twin_vaf, "closed_loop_vaf_pct": cl["vaf_holdout_pct"],
                            "closed_loop_method": cl["method"], "input": "att_sp" if through_angle else "rate_sp",
                            "plant_indirect_vaf_pct": ind.get("vaf_holdout_pct")}
    return jsonable({
        "vehicle": out.name, "start_vehicle": str(source), "axes": list(targets),
        "inertia_kgm2": cal.inertia_kgm2, "lag_s": cal.lag_s, "delay_s": cal.delay_s,
        "rotor_inertia_kgm2": cal.rotor_inertia_kgm2, "hforce_N_per_mps": cal.hforce_N_per_mps,
        "residual": {a: {"max_db": r.max_db, "max_deg": r.max_deg, "w_rad_s": r.w_rad_s, "error_db": r.error_db,
                         "error_deg": r.error_deg} for a, r in cal.residual.items()},
        "residual_start": {a: {"max_db": r.max_db, "max_deg": r.max_deg} for a, r in cal.residual_start.items()},
        "at_bounds": list(cal.at_bounds), "prescaled": prescaled, "prediction": prediction, "notes": notes})


def _physical(inertia, fixed) -> list:
    """Principal moments made to obey a rigid body's rule (each at most the sum of the other two), changing the
    moments of the axes not in ``fixed`` (indices: those the log determined) where it can: a free moment above
    the sum is capped at it; below, the free moments are raised in proportion (all of them when every axis is
    fixed)."""
    i = [float(x) for x in inertia]
    for c in range(3):
        rest = sum(i) - i[c]
        if i[c] <= rest:
            continue
        if c not in fixed:
            i[c] = rest * (1.0 - 1e-6)
            continue
        free = [k for k in range(3) if k != c and k not in fixed] or [k for k in range(3) if k != c]
        need = i[c] * (1.0 + 1e-6) - rest  # added to the free moments, in proportion to them
        total = sum(i[k] for k in free)
        for k in free:
            i[k] += need * i[k] / total
    return i


STAGE = Stage("calibrate", upstream=("identify",), settings=(), run=run)
