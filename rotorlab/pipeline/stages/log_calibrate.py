"""Log stage 2, calibrate: the twin's inertia, motor poles and delays fitted to the identified per-axis plants
(:func:`rotorlab.vehicles.fit_axes.calibrate_axes_staged`), and the calibrated twin's prediction of the held-out flight.

The starting twin is ``--vehicle`` (a vehicle TOML, e.g. from ``rotorlab vehicle new``, or a shipped name), else
the shipped ``x500`` (PX4's reference vehicle). A log's plant runs from the autopilot's normalised torque to rad/s;
the twin's from its axis command (%) to deg/s, with a normalised torque of 1 a differential command of 100 %
(:data:`rotorlab.sim.control.autopilot.TORQUE_TO_PCT`); the target is converted accordingly. PX4's allocator and
ArduPilot's mixer scale the torque by the airframe's geometry, which the twin does not model, so the torque gain
per inertia the log shows can be far from the starting twin's: where an axis's gain at :data:`W_START_RAD_S`
differs by more than :data:`MAX_START_RATIO`, that axis's inertia is first scaled to match it (the fit's inertia
range is a factor of 3 around its start), and the report says so. The roll and pitch moments, the motor lag and
the delay are then refined on the flight's identification windows (:func:`refine_on_flight`; at most
``MAX_FIT_SAMPLES`` samples, the identification's own budget), where the axes' models disagree on the motors they
share, and yaw is fitted again with the refined motors held.

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
import scipy.optimize as so

from rotorlab import lti
from rotorlab.ident.flightlogs import read_flight_log
from rotorlab.ident.flightlogs.identify import (
    MAX_FIT_SAMPLES,
    MIN_SAMPLES,
    angle_cascade,
    controller_at,
    holdout_prediction,
    loop_substeps,
)
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
    axis_residuals,
    calibrate_axes,
    calibrate_axes_staged,
    rotor_groups,
    twin_response,
    twin_scene,
    write_calibrated,
)

__all__ = ["STAGE", "DEFAULT_VEHICLE", "twin_plant", "twin_plant_continuous", "target_model", "twin_holdout_vaf",
           "FlightLoop", "flight_loop", "twin_prediction", "FlightRefinement", "refine_on_flight"]

DEFAULT_VEHICLE = "x500"
W_START_RAD_S = 1.0  # where the starting twin's gain is compared with the log's: the fit band's lower end, where the
# rate response is the integrator b / s alone (motor pole and delay do not count yet)
MAX_START_RATIO = 2.0  # well inside the fit's inertia range (a factor of 3 either way)
# the twin's per-axis linearisation carries every state of the airframe; the other axes' modes, neither driven nor
# seen, cancel to this tolerance (python-control's default keeps them in a yaw model: 12 states instead of 4)
MINREAL_TOL = 1e-6
REFINE_INERTIA_RANGE = (0.8, 1.25)  # of the frequency calibration's moment: the refinement corrects it
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


@dataclasses.dataclass(frozen=True)
class FlightLoop:
    """One axis of a flight log set up for the twin's free-run prediction: the record, the log's controller at the
    simulation step (``dt / substeps``), the input that drives the loop and the autopilot's gyro filter."""

    axis: str
    rec: object  # rotorlab.ident.flightlogs Record with the input and "rate"
    controller: ct.StateSpace
    feedback: object  # plant outputs the controller sees (0, or (0, 1): rate and angle)
    u_name: str  # "rate_sp", or "att_sp" through the angle loop
    substeps: int
    gyro_filter: ct.StateSpace | None  # at dt / substeps


def flight_loop(log, axis: str, dt_s: float, angle: tuple | None = None) -> FlightLoop:
    """The loop of ``axis`` in ``log`` at the record period ``dt_s``: the log's rate controller driven by the
    logged rate set-point, or with ``angle = (angle_p, ff)`` the angle and rate controllers
    (:func:`rotorlab.ident.flightlogs.identify.angle_cascade`) driven by the attitude set-point.

    Examples
    --------
    >>> log = read_flight_log("flight.ulg")  # doctest: +SKIP
    >>> loop = flight_loop(log, "roll", 0.004)  # doctest: +SKIP
    >>> loop.u_name, loop.substeps  # doctest: +SKIP
    ('rate_sp', 1)
    """
    C = autopilot_controller(log, axis)
    sub = loop_substeps(C, dt_s)
    if angle is None:
        rec = log.record(axis, ("rate_sp", "rate"), rate_hz=1.0 / dt_s)
        K, feedback, u_name = controller_at(C, rec.dt / sub), 0, "rate_sp"
    else:
        rec = angle_record(log, axis, dt_s)
        K, feedback, u_name = angle_cascade(C, *angle, rec.dt / sub), (0, 1), "att_sp"
    gyro_filter = autopilot_gyro_filter(log)
    return FlightLoop(axis, rec, K, feedback, u_name, sub, None if gyro_filter is None else gyro_filter(rec.dt / sub))


def twin_prediction(loop: FlightLoop, v, windows) -> tuple[float, list]:
    """(pooled free-run VAF %, [(t_s, rate, predicted rate)] per window) of the twin ``v`` (linearised, gimbal
    scene) closed with the log's controller in ``loop`` on ``windows`` (``Window`` list), each window's initial
    state estimated (:func:`rotorlab.ident.flightlogs.identify.holdout_prediction`).

    Examples
    --------
    >>> from rotorlab.ident.flightlogs.windows import Window
    >>> vaf_pct, pred = twin_prediction(loop, load_vehicle("x500"), [Window(20.0, 40.0, "held out")])  # doctest: +SKIP
    """
    Gc, delay_s = twin_plant_continuous(v, loop.axis)
    dt = loop.rec.dt / loop.substeps
    if loop.u_name == "rate_sp":
        plant = lti.c2d_zoh_delay(Gc, dt, delay_s)
    else:
        plant = axis_plant(Gc, delay_s, dt)  # [rate, angle]: the attitude the rate integrated
    if loop.gyro_filter is not None:  # the controller and the log both see the rate through the gyro filter
        F = loop.gyro_filter
        plant = ct.series(plant, F if loop.u_name == "rate_sp" else ct.append(F, ct.ss([], [], [], [[1.0]], dt)))
    cl_fast = _closed_loop(plant, loop.controller, loop.feedback)
    cl = IdentifiedModel(sys=lift_interpolated(cl_fast, loop.substeps)[0, :], method="twin-closed-loop",
                         settings={"substeps": loop.substeps})
    return holdout_prediction(cl, loop.rec, loop.u_name, "rate", windows)


def _windows(spans, reason: str) -> list:
    return [Window(float(a), float(b), reason) for a, b in spans]


def _fit_windows(spans, dt_s: float) -> list:
    """The first identification windows holding at most ``MAX_FIT_SAMPLES`` samples of period ``dt_s`` together
    (the last one cut), the identification's own budget for a fit: a long log costs no more than a short one. The
    time-span form of :func:`rotorlab.ident.flightlogs.identify._capped`, which caps index runs: the twin's
    prediction takes windows (:func:`twin_prediction`)."""
    out, left_s = [], MAX_FIT_SAMPLES * dt_s
    for a, b in spans:
        if left_s < MIN_SAMPLES * dt_s:
            break
        stop = min(float(b), float(a) + left_s)
        out.append(Window(float(a), stop, "identification"))
        left_s -= stop - float(a)
    return out


def twin_holdout_vaf(log, v, axis: str, dt_s: float, holdout, angle: tuple | None = None) -> float:
    """Free-run VAF (%) of the twin closed with the log's rate controller on the held-out windows, driven by the
    logged rate set-point; with ``angle = (angle_p, ff)`` closed with the angle and rate controllers
    (:func:`rotorlab.ident.flightlogs.identify.angle_cascade`) and driven by the attitude set-point, as the plant
    through the angle loop was fitted and scored (:func:`flight_loop`, :func:`twin_prediction`)."""
    return twin_prediction(flight_loop(log, axis, dt_s, angle), v, _windows(holdout, "held out"))[0]


@dataclasses.dataclass(frozen=True)
class FlightRefinement:
    """Result of :func:`refine_on_flight`: the refined vehicle and, per axis, the free-run VAF (%) on the
    identification windows before and after; ``evaluations`` counts the fit's evaluations (each predicts every
    axis of its rotor group);
    ``notes``: a parameter that ended on a bound, a rotor group whose calibration fitted the flight best."""

    vehicle: object
    vaf_before: dict
    vaf_after: dict
    evaluations: int
    notes: tuple = ()


def refine_on_flight(v, loops: dict) -> FlightRefinement:
    """The twin's inertia (one moment per axis of ``loops``), motor lag and delay refined by output error on the
    flight itself: the twin closed with the log's controller, driven by the logged input, predicts the logged rate
    on the identification windows (free run, initial state estimated), the data and criterion of the plant through
    the known controller (:func:`rotorlab.ident.flightlogs.identify.identify_plant_indirect`).

    The frequency-domain calibration (:func:`rotorlab.vehicles.fit_axes.calibrate_axes`) matches each axis's
    identified model, but where the rotors are shared (X and hexa layouts: one motor lag and delay for roll and
    pitch) the axes' models ask for different motors and the least-squares compromise over 1-30 rad/s is not the
    one that predicts the flight best (the S250 log: roll's model asks for a 123 ms lag, pitch's for 111 ms). Here
    the compromise is made on the flight: each axis counts ``var(e) / var(rate)`` over its identification windows
    (the VAF deficit), summed over the axes that share rotors. The held-out windows are not used.

    Parameters are kept physical: the moments within :data:`REFINE_INERTIA_RANGE` of the calibration's (a
    correction, not a new fit; a moment that is not refined is moved only where the triangle inequality needs
    it), the lag within :data:`rotorlab.vehicles.fit_axes.LAG_RANGE_S`, the delay in whole physics steps (MuJoCo
    realises it with its actuator history), searched step by step from the calibration's while the fit improves.
    Rotor groups that drive different axes (the plus layout's pairs) are refined separately.

    Parameters
    ----------
    v : VehicleSpec
        The calibrated twin.
    loops : dict
        ``axis -> (FlightLoop, windows)``: the axis's loop (:func:`flight_loop`) and its identification windows
        (``Window`` list).

    Returns
    -------
    FlightRefinement
        The refined vehicle; a problem whose fit does not improve keeps the calibration's values.

    Examples
    --------
    >>> loop = flight_loop(log, "pitch", 0.0049)  # doctest: +SKIP
    >>> refine_on_flight(v, {"pitch": (loop, windows)}).vaf_after  # doctest: +SKIP
    """
    groups = rotor_groups(v)
    problems = [(None, list(loops))] if None in groups else [(a, [a]) for a in loops if a in groups]
    count = [0]

    def scored(vehicle, axes):
        count[0] += 1
        out = {}
        for a in axes:
            loop, windows = loops[a]
            vaf_pct, pred = twin_prediction(loop, vehicle, windows)
            y = np.concatenate([p[1] for p in pred])
            e = y - np.concatenate([p[2] for p in pred])
            out[a] = (vaf_pct, (e - e.mean()) / (np.std(y) * math.sqrt(e.size)))
        return out

    before = {a: r[0] for a, r in scored(v, list(loops)).items()}
    notes = []
    for group, axes in problems:
        v, said = _refine_group(v, axes, groups[group], scored)
        notes += said
    after = {a: r[0] for a, r in scored(v, list(loops)).items()}
    return FlightRefinement(v, before, after, count[0], tuple(notes))


def _refine_group(v, axes, rotors, scored) -> tuple:
    """:func:`refine_on_flight` for the ``axes`` one rotor group drives: (vehicle, notes)."""
    idx = [INERTIA_INDEX[a] for a in axes]
    i0 = np.array([v.inertia_kgm2[k] for k in idx])
    lag0 = float(np.mean([v.rotor.lag_s[k] for k in rotors]))
    step0 = round(float(np.mean([v.rotor.delay_s[k] for k in rotors])) / PHYSICS_DT_S)

    def vehicle_at(x, steps):
        inertia = list(v.inertia_kgm2)
        for k, val in zip(idx, i0 * np.exp(x[:-1]), strict=True):
            inertia[k] = float(val)
        lag, delay = list(v.rotor.lag_s), list(v.rotor.delay_s)
        for k in rotors:
            lag[k], delay[k] = lag0 * math.exp(float(x[-1])), steps * PHYSICS_DT_S
        rotor = dataclasses.replace(v.rotor, lag_s=tuple(lag), delay_s=tuple(delay))
        return dataclasses.replace(v, inertia_kgm2=tuple(_physical(inertia, set(idx))), rotor=rotor)

    def cost(vehicle):
        return np.concatenate([r[1] for r in scored(vehicle, axes).values()])

    lo = np.array([math.log(REFINE_INERTIA_RANGE[0])] * len(idx) + [math.log(LAG_RANGE_S[0] / lag0)])
    hi = np.array([math.log(REFINE_INERTIA_RANGE[1])] * len(idx) + [math.log(LAG_RANGE_S[1] / lag0)])

    def solve(steps, x_start):
        # xtol: 0.1 % in the moments and the lag, far inside what a flight record determines
        sol = so.least_squares(lambda x: cost(vehicle_at(x, steps)), np.clip(x_start, lo + 1e-9, hi - 1e-9),
                               bounds=(lo, hi), diff_step=1e-3, xtol=1e-3, ftol=1e-5)
        return float(np.sum(sol.fun ** 2)), sol.x

    start_cost = float(np.sum(cost(v) ** 2))
    tried = {step0: solve(step0, np.zeros(len(idx) + 1))}
    for direction in (-1, 1):  # one step either way, then on while the fit improves
        s = step0 + direction
        while DELAY_RANGE_S[0] <= s * PHYSICS_DT_S <= DELAY_RANGE_S[1] and s not in tried:
            tried[s] = solve(s, tried[s - direction][1])
            if tried[s][0] >= tried[s - direction][0]:
                break
            s += direction
    steps, (best, x_best) = min(tried.items(), key=lambda kv: kv[1][0])
    name = "/".join(axes)
    if best >= start_cost:
        return v, [f"{name}: the calibration's values fit the flight best"]
    labels = [f"inertia {a}" for a in axes] + ["motor lag"]
    return vehicle_at(x_best, steps), [f"{name}: {p} at its {'lower' if xi - a < b - xi else 'upper'} bound"
                                       for p, xi, a, b in zip(labels, x_best, lo, hi, strict=True)
                                       if min(xi - a, b - xi) < 1e-3]


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
    log = read_flight_log(ctx.opts.log)
    pairs = {axis: _pair(ident["axes"][axis]) for axis in targets}
    flight_loops = {axis: flight_loop(log, axis, cl["dt_s"], angle) for axis, (cl, _, angle) in pairs.items()}
    # the tilt axes' shared motors compromised on the flight itself (refine_on_flight); yaw borrows the motors
    loops = {axis: (flight_loops[axis], _fit_windows(cl["ident"], cl["dt_s"]))
             for axis, (cl, _, _) in pairs.items() if axis != "yaw"}
    refined = refine_on_flight(cal.vehicle, loops) if loops else None
    frequency_fit = {"inertia_kgm2": cal.inertia_kgm2, "lag_s": cal.lag_s, "delay_s": cal.delay_s,
                     "residual": {a: {"max_db": r.max_db, "max_deg": r.max_deg} for a, r in cal.residual.items()}}
    if refined is not None and refined.vehicle != cal.vehicle:
        v_ref, at_bounds = refined.vehicle, cal.at_bounds
        if "yaw" in targets:  # yaw's inertia and rotor terms again, with the refined motors held
            yaw = calibrate_axes(v_ref, {"yaw": targets["yaw"]}, fit_motors=False)
            v_ref, at_bounds = yaw.vehicle, tuple(dict.fromkeys(at_bounds + yaw.at_bounds))
        cal = dataclasses.replace(
            cal, vehicle=v_ref, at_bounds=at_bounds, inertia_kgm2=tuple(v_ref.inertia_kgm2), lag_s=tuple(v_ref.rotor.lag_s),
            delay_s=tuple(v_ref.rotor.delay_s), residual=axis_residuals(v_ref, targets),
            rotor_inertia_kgm2=v_ref.rotor.inertia_kgm2 if cal.rotor_inertia_kgm2 is not None else None,
            hforce_N_per_mps=v_ref.rotor.hforce_N_per_mps if cal.hforce_N_per_mps is not None else None)
    out = write_calibrated(source, cal, ctx.work / "vehicle.toml",
                           note=f"calibrated to the flight log {ident['log']} (rotorlab pipeline --log)")
    v = load_vehicle(str(out))
    prediction = {}
    for axis, (cl, ind, angle) in pairs.items():
        twin_vaf = twin_prediction(flight_loops[axis], v, _windows(cl["holdout"], "held out"))[0]
        prediction[axis] = {"twin_vaf_pct": twin_vaf, "closed_loop_vaf_pct": cl["vaf_holdout_pct"],
                            "closed_loop_method": cl["method"], "input": "att_sp" if angle else "rate_sp",
                            "plant_indirect_vaf_pct": ind.get("vaf_holdout_pct")}
    flight_fit = None if refined is None else {
        "ident_vaf_before_pct": refined.vaf_before, "ident_vaf_after_pct": refined.vaf_after,
        "evaluations": refined.evaluations, "notes": list(refined.notes), "frequency_fit": frequency_fit}
    return jsonable({
        "vehicle": out.name, "start_vehicle": str(source), "axes": list(targets),
        "inertia_kgm2": cal.inertia_kgm2, "lag_s": cal.lag_s, "delay_s": cal.delay_s,
        "rotor_inertia_kgm2": cal.rotor_inertia_kgm2, "hforce_N_per_mps": cal.hforce_N_per_mps,
        "residual": {a: {"max_db": r.max_db, "max_deg": r.max_deg, "w_rad_s": r.w_rad_s, "error_db": r.error_db,
                         "error_deg": r.error_deg} for a, r in cal.residual.items()},
        "residual_start": {a: {"max_db": r.max_db, "max_deg": r.max_deg} for a, r in cal.residual_start.items()},
        "at_bounds": list(cal.at_bounds), "prescaled": prescaled, "prediction": prediction, "flight_fit": flight_fit,
        "notes": notes})


def _pair(a: dict) -> tuple:
    """(closed-loop model, plant through the controller, angle loop or None) of an identified axis: the pair that
    shares the input of the plant used, the rate set-point or in an angle mode the attitude set-point."""
    if a["use"] == "plant-indirect-angle":
        ind = a["plant-indirect-angle"]
        return a["closed-loop-angle"], ind, (ind["angle_p"], ind["ff"])
    return a["closed-loop"], a.get("plant-indirect") or {}, None


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
