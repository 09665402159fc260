"""A flight log end to end: read, pick windows, identify every asked axis, write one model file per axis and
the log report. ``rotorlab ident FLIGHT.ulg|FLIGHT.bin|CSV_DIR`` calls :func:`identify_flight_log`."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rotorlab.errors import DataError

from ..metrics import vaf
from . import read_flight_log
from .flightlog import FlightLog
from .identify import AxisModel, identify_direct, identify_plant_indirect, identify_plant_through_angle_loop
from .names import AXES
from .plant_structures import MOTOR_PARAMS, SHARES_MOTORS, plant_structure, rate_angle_plant_structure
from .windows import MIN_RMS, holdout_excitation, select_windows

__all__ = ["FlightLogResult", "identify_flight_log", "autopilot_controller", "autopilot_gyro_filter", "controller_params",
           "MAX_IDENT_HZ", "angle_loop_share", "angle_record", "ANGLE_LOOP_VAF"]

# The identification rate of a log logged faster (default ``rate_hz``): the rate loop's informative band ends near
# 15-30 Hz, so 250 Hz keeps 8x margin; a 1 kHz log identified at 1 kHz costs 4x the samples and far more in the
# subspace fits for nothing. A loop faster than the log's rate is simulated between samples (identify_plant_indirect)
MAX_IDENT_HZ = 250.0
# A rate set-point the angle law explains to this VAF (%) from the measured attitude is the angle loop's output: on
# the ArduCopter development log (STABILIZE) 98-99 %; a pilot's or an autotune's rate input is not a function of
# the attitude
ANGLE_LOOP_VAF = 90.0


@dataclass
class FlightLogResult:
    """What :func:`identify_flight_log` found: the log, per axis its models, the files written, and notes
    (skipped models and why)."""

    log: FlightLog
    models: dict = field(default_factory=dict)
    files: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def controller_params(log: FlightLog):
    """The log's parameters with the names of older firmware mapped onto the current laws' names
    (:func:`rotorlab.autopilots.legacy.upgrade`), and the list of what was mapped or filled (``Mapped``);
    ``(log.params, [])`` where ``rotorlab.autopilots`` is not installed.

    Examples
    --------
    >>> params, mapped = controller_params(read_flight_log("old.BIN"))  # doctest: +SKIP
    >>> [m.text() for m in mapped]  # doctest: +SKIP
    """
    if importlib.util.find_spec("rotorlab.autopilots") is None:
        return dict(log.params), []
    from rotorlab.autopilots import legacy

    return legacy.upgrade(log.autopilot, log.params)


def autopilot_controller(log: FlightLog, axis: str):
    """The autopilot's rate controller of ``axis`` from the log's parameters, as a python-control LTI system at the
    loop rate, from ``rotorlab.autopilots`` (``get(autopilot).rate_controller_lti``); ``None`` where that package
    is not installed. The logged rate has been through the gyro filter already (``gyro_filter=False``). Parameters
    of older firmware are mapped first (:func:`controller_params`).

    Raises
    ------
    DataError
        A parameter the controller law needs is not in the log.
    """
    if importlib.util.find_spec("rotorlab.autopilots") is None:
        return None
    from rotorlab import autopilots

    ap = autopilots.get(log.autopilot)
    params, _ = controller_params(log)
    try:
        return ap.rate_controller_lti(params, axis, 1.0 / ap.loop_hz(params), gyro_filter=False)
    except KeyError as exc:
        raise DataError(f"{log.path}: parameter {exc.args[0]} is not in the log; the {log.autopilot} rate "
                        f"controller of the {axis} axis needs it for the plant through the known controller") from None


def autopilot_gyro_filter(log: FlightLog):
    """``dt -> control.StateSpace``: the autopilot's gyro low-pass (``GYRO_FILTER_PARAM`` of its
    ``rotorlab.autopilots`` module, from the log's parameters, older names mapped) at sample time ``dt``, the filter
    the logged rate has been through; ``None`` where ``rotorlab.autopilots`` is not installed or the log does not
    hold the parameter. A cutoff of 0 (off, or a legacy log whose driver filtered the gyro) is no filter.

    Examples
    --------
    >>> F = autopilot_gyro_filter(read_flight_log("flight.ulg"))  # doctest: +SKIP
    >>> F(0.004).nstates  # doctest: +SKIP
    2
    """
    if importlib.util.find_spec("rotorlab.autopilots") is None:
        return None
    from rotorlab import autopilots
    from rotorlab.autopilots import filters

    params, _ = controller_params(log)
    name = autopilots.get(log.autopilot).GYRO_FILTER_PARAM
    if name not in params:
        return None
    cutoff_hz = float(params[name])
    return lambda dt: filters.butter2_ss(1.0 / dt, cutoff_hz)


def _motors(res: FlightLogResult, axis: str) -> list | None:
    """The motors' lag and delay for ``axis``'s structure, one motor path per axis it shares them with
    (:data:`~.plant_structures.SHARES_MOTORS`) that this run fitted through the controller; ``None`` (estimated on
    ``axis`` itself, with a note) where there are none."""
    fitted = [res.models[a]["plant-indirect"].extra["params"] for a in SHARES_MOTORS.get(axis, ())
              if "plant-indirect" in res.models.get(a, {})]
    if not fitted:
        if axis in SHARES_MOTORS:
            res.notes.append(f"{axis}: motor lag and delay estimated on {axis} alone (identify "
                             f"{' and '.join(SHARES_MOTORS[axis])} with it to take them from there)")
        return None
    return [{k: float(p[k]) for k in MOTOR_PARAMS} for p in fitted]


def identify_flight_log(path, out_dir, axes=None, *, windows=None, holdout: float = 0.4, rate_hz=None,
                        allow_truncated: bool = False, controller=autopilot_controller,
                        report: bool = True, imu_mount: tuple | None = None) -> FlightLogResult:
    """Identify every axis of ``axes`` in a flight log and write the results to ``out_dir``.

    Per axis: the closed loop (rate_sp -> rate), the plant (rate_out -> rate) where the log has the rate-loop
    output, and the plant through the known controller where ``controller(log, axis)`` gives one (the axis's
    structure of :mod:`~rotorlab.ident.flightlogs.plant_structures`, the log's gyro low-pass in it
    (:func:`autopilot_gyro_filter`), yaw with the motors' lag and delay of the roll and pitch fits, one motor path
    each, and the IMU's mount where ``imu_mount`` gives it). An axis whose
    closed loop cannot be identified ends the run (DataError); a plant model that cannot be fitted is a note. Files:
    ``<axis>.json`` (the plant: through the controller where known, else direct; else the closed loop), one
    ``<axis>-<kind>.json`` per model, and ``report.html`` with its PNGs. Units are recorded in every model file.

    Parameters
    ----------
    path : str or Path
        ``.ulg``, ``.bin``/``.log``, or a ulog2csv folder.
    out_dir : str or Path
    axes : sequence of str, optional
        The axes to identify; each must be identifiable (else DataError). ``None``: every axis the log has with
        excitation; an axis without is a note, and DataError only when none is left.
    windows : list of (start_s, stop_s), optional
        Identification windows instead of the automatic ones.
    holdout : float
        Fraction of the airborne (or excitation) time held out at its end to score the models.
    rate_hz : float, optional
        Identification rate (default: the slowest signal of each record, at most :data:`MAX_IDENT_HZ`).
    controller : callable or None
        ``controller(log, axis) -> LTI or None``.
    imu_mount : (float, float), optional
        The IMU mount's natural frequency, Hz, and damping ratio, from the vehicle's description (a twin's
        ``[imu] mount_frequency_hz`` and ``mount_damping_ratio``): the mode in every axis's plant structure
        (:func:`~.plant_structures.with_imu_mount`). A rate-loop record does not determine it; where the gyro
        low-pass passes it (PX4's 40 Hz against a 60 Hz mount) the plant models miss it without.

    Raises
    ------
    DataError
        A log that cannot be read or identified (what is missing is in the message).

    Examples
    --------
    >>> res = identify_flight_log("flight.ulg", "models/")  # doctest: +SKIP
    >>> res.models["roll"]["closed-loop"].vaf_holdout  # doctest: +SKIP
    """
    from rotorlab.ident.modelio import save_model

    kwargs = {"allow_truncated": True} if allow_truncated else {}
    log = read_flight_log(path, **kwargs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res = FlightLogResult(log)
    strict = axes is not None
    axes = list(axes) if strict else [a for a in AXES if a in log.axes]
    mapped = controller_params(log)[1] if controller is not None else []
    res.notes += [f"controller parameter {m.text()}" for m in mapped]
    missing = [a for a in axes if a not in log.axes]
    if missing:
        raise DataError(f"{log.path}: no rate set-point and measured rate for {', '.join(missing)}; the log has "
                        f"{', '.join(log.axes) or 'none'}")
    # roll and pitch first: yaw takes their motors' lag and delay (plant_structures.SHARES_MOTORS)
    axes.sort(key=lambda a: AXES.index(a) if a in AXES else len(AXES))
    for axis in axes:
        # each model on the signals it needs at their own rate: a slow rate-loop output (PX4 2016 logged
        # actuator_controls_0 at half the set-point's rate) must not slow the closed loop's record down
        has_out = "rate_out" in log.signals[axis]
        rec = _record(log, axis, ("rate_sp", "rate"), rate_hz)
        recs = {"closed-loop": rec, "plant-indirect": rec}
        models = {}
        try:
            split_cl = select_windows(log, rec, "rate_sp", "rate", holdout=holdout, override=windows)
            models["closed-loop"] = identify_direct(rec, split_cl, "closed-loop")
        except DataError as exc:
            if strict:
                raise
            res.notes.append(f"{axis}: not identified: {exc}")
            continue
        rms, coh = holdout_excitation(split_cl)
        if rms < MIN_RMS["rate_sp"]:
            res.notes.append(f"{axis}: the held-out part is not excited (rate_sp RMS {rms:.3g} rad/s, detrended, "
                             f"under {MIN_RMS['rate_sp']:g}; coherence {coh:.2f} in the band): its VAF scores the noise "
                             "and disturbances, not the model; hold out an excited part (--holdout, --window)")
        share = angle_loop_share(log, axis, rec, split_cl.holdout)
        if share is not None:
            models["closed-loop"].extra["angle_loop"] = share
            if share["vaf"] >= ANGLE_LOOP_VAF:
                law = f" (the log's angle P: {share['P_log']:.3g})" if "P_log" in share else ""
                res.notes.append(
                    f"{axis}: the logged rate set-point is the angle loop's output: rate_sp = {share['P']:.3g} "
                    f"(att_sp - att) + {share['F']:.2f} d(att_sp)/dt explains {share['vaf']:.1f} % of it on the "
                    f"held-out part{law}. It is computed from the attitude that integrates the rate, so the "
                    "closed-loop model (rate_sp -> rate) fits that feedback as well as the rate loop, and a plant "
                    "closed with the rate controller alone cannot reproduce it: that law solved for the attitude "
                    f"and differentiated predicts {share['kinematic_vaf']:.1f} % of the held-out rate with no "
                    f"plant at all (the closed-loop model: {models['closed-loop'].vaf_holdout:.1f} %); the models "
                    "from the attitude set-point (closed-loop-angle, plant-indirect-angle) are the comparable pair")
        if has_out:
            # the closed loop decides whether the axis can be identified at all; a plant the rate-loop output
            # does not excite enough is a note, not the end of the run
            try:
                recs["plant"] = _record(log, axis, ("rate_out", "rate"), rate_hz)
                split_p = select_windows(log, recs["plant"], "rate_out", "rate", holdout=holdout, override=windows)
                models["plant"] = identify_direct(recs["plant"], split_p, "plant")
            except DataError as exc:
                res.notes.append(f"{axis}: no direct plant model: {exc}")
        else:
            res.notes.append(f"{axis}: no rate-loop output in the log: plant only through the controller")
        C = controller(log, axis) if controller is not None else None
        if C is not None:
            try:
                structure = plant_structure(axis, autopilot_gyro_filter(log), _motors(res, axis), imu_mount)
                models["plant-indirect"] = identify_plant_indirect(rec, split_cl, C, structure)
                models["plant-indirect"].extra["controller_params_mapped"] = [m.text() for m in mapped]
            except (DataError, ValueError) as exc:
                res.notes.append(f"{axis}: no plant through the controller: {exc}")
        else:
            res.notes.append(f"{axis}: plant through the known controller skipped (rotorlab.autopilots not installed)")
        if C is not None and share is not None and share["vaf"] >= ANGLE_LOOP_VAF and "P_log" in share:
            # the angle mode's input is the attitude set-point: the closed loop from it and the plant through the
            # angle and rate controllers, the pair the indirect route compares when the rate set-point is fed back
            try:
                rec_a = angle_record(log, axis, rec.dt)
                split_a = select_windows(log, rec_a, "att_sp", "rate", holdout=holdout, override=windows, min_rms={})
                models["closed-loop-angle"] = identify_direct(rec_a, split_a, "closed-loop-angle")
                models["plant-indirect-angle"] = identify_plant_through_angle_loop(
                    rec_a, split_a, C, share["P_log"], share["F"],
                    rate_angle_plant_structure(gyro_filter=autopilot_gyro_filter(log)))
                recs["closed-loop-angle"] = recs["plant-indirect-angle"] = rec_a
            except (DataError, ValueError) as exc:
                models.pop("closed-loop-angle", None)
                res.notes.append(f"{axis}: no plant through the angle and rate controllers: {exc}")
        res.models[axis] = models
        for kind, m in models.items():
            res.files.append(_save(save_model, out / f"{axis}-{kind}.json", m, log, recs[kind]))
        main = next(k for k in ("plant-indirect", "plant", "closed-loop") if k in models)
        res.files.append(_save(save_model, out / f"{axis}.json", models[main], log, recs[main]))
    if not res.models:
        why = [n for n in res.notes if not n.startswith("controller parameter ")]
        raise DataError(f"{log.path}: no axis could be identified: " + "; ".join(why))
    if report:
        from .report import write_report

        res.files += write_report(res, out)
    return res


def angle_loop_share(log: FlightLog, axis: str, rec, windows) -> dict | None:
    """How much of the logged rate set-point the angle loop explains: ``rate_sp = P (att_sp - att) + F
    d(att_sp)/dt`` (the angle error wrapped to +-pi, the set-point's rate by backward difference: the angle P and
    feed-forward of ArduPilot and PX4) fitted by least squares on ``windows`` of the log at ``rec``'s rate, each
    about its mean. ``None`` where the log has no ``att`` or ``att_sp`` for ``axis``.

    Returns
    -------
    dict
        ``vaf`` (%), ``P`` (1/s), ``F`` (1), where ``rotorlab.autopilots`` has the autopilot's angle law and
        the log its parameters ``P_log`` (the angle P of the log's parameters), and ``kinematic_vaf`` (%): the
        held-out rate predicted by that law solved for the attitude (``P_log``, else ``P``), no plant involved.

    Examples
    --------
    >>> share = angle_loop_share(log, "roll", rec, split.holdout)  # doctest: +SKIP
    >>> share["vaf"], share["P"]  # doctest: +SKIP
    """
    if not {"att", "att_sp"} <= set(log.signals[axis]):
        return None
    r = log.record(axis, ("rate_sp", "att", "att_sp", "rate"), rate_hz=1.0 / rec.dt)
    cols, target, sps = [], [], []
    for w in windows:
        idx = np.flatnonzero((r.t_s >= w.start_s) & (r.t_s < w.stop_s))
        if len(idx) < 32:
            continue
        sp = np.unwrap(r.data["att_sp"][idx])
        err = np.angle(np.exp(1j * (r.data["att_sp"][idx] - r.data["att"][idx])))
        ff = np.diff(sp, prepend=sp[0]) / r.dt
        cols.append(np.column_stack([err - err.mean(), ff - ff.mean()]))
        target.append(r.data["rate_sp"][idx] - r.data["rate_sp"][idx].mean())
        sps.append((sp, r.data["rate_sp"][idx], r.data["rate"][idx]))
    if not cols:
        return None
    X, y = np.vstack(cols), np.concatenate(target)
    if not np.var(y) > 0:
        return None
    theta = np.linalg.lstsq(X, y, rcond=None)[0]
    out = {"vaf": float(max(0.0, 100.0 * (1.0 - np.var(y - X @ theta) / np.var(y)))), "P": float(theta[0]),
           "F": float(theta[1])}
    if importlib.util.find_spec("rotorlab.autopilots") is not None:
        from rotorlab import autopilots

        try:
            law = autopilots.get(log.autopilot).attitude_controller_lti(controller_params(log)[0], axis, r.dt)
            out["P_log"] = float(np.asarray(law.D)[0, 0])
        except (KeyError, AttributeError, ValueError):
            pass  # no angle law or parameter for it: the fitted P stands alone
    out["kinematic_vaf"] = _angle_law_inverted_vaf(sps, out.get("P_log", out["P"]), out["F"], r.dt)
    return out


def _angle_law_inverted_vaf(windows, P: float, F: float, dt: float) -> float:
    """Pooled VAF (%) of the rate predicted with no plant: the angle law ``rate_sp = P (att_sp - att) + F
    d(att_sp)/dt`` solved for the attitude and differentiated, on ``[(att_sp, rate_sp, rate)]`` windows (each
    about its mean). Where this scores as well as a closed-loop model from the rate set-point, that model has
    learnt the angle law's feedback, not the rate loop. Derivatives are centred differences: a backward one is
    half a sample late, 21 ms at a 24 Hz log."""
    if not P > 0:
        return float("nan")
    ys, yh = [], []
    for sp, rsp, rate in windows:
        att = sp - (rsp - F * np.gradient(sp, dt)) / P
        pred = np.gradient(att, dt)
        ys.append(rate - rate.mean())
        yh.append(pred - pred.mean())
    return float(vaf(np.concatenate(ys), np.concatenate(yh))[0])


def angle_record(log: FlightLog, axis: str, dt: float):
    """The attitude set-point, rate and attitude of ``axis`` at ``dt`` (a ``Record``), the angles continuous: the
    set-point unwrapped, the attitude that set-point less the wrapped angle error (a yaw crossing +-pi stays one
    branch).

    Examples
    --------
    >>> rec = angle_record(read_flight_log("flight.bin"), "roll", 1 / 25)  # doctest: +SKIP
    >>> sorted(rec.data)  # doctest: +SKIP
    ['att', 'att_sp', 'rate']
    """
    r = log.record(axis, ("att_sp", "rate", "att"), rate_hz=1.0 / dt)
    sp = np.unwrap(r.data["att_sp"])
    err = np.angle(np.exp(1j * (r.data["att_sp"] - r.data["att"])))
    return replace(r, data={**r.data, "att_sp": sp, "att": sp - err})


def _record(log: FlightLog, axis: str, names, rate_hz):
    if rate_hz is None:
        rate_hz = min(MAX_IDENT_HZ, min(log.series(axis, n).rate_hz for n in names))
    return log.record(axis, names, rate_hz=rate_hz)


def _save(save_model, path, m: AxisModel, log: FlightLog, rec):
    extra = {"log": log.path, "format": log.format, "autopilot": log.autopilot, "version": log.version,
             "axis": m.axis, "kind": m.kind, "sources": {k: rec.sources[k] for k in (m.input, m.output)
                                                          if k in rec.sources},
             "time_base": "s (log stamps converted from microseconds)",
             "windows": [[w.start_s, w.stop_s, w.reason] for w in m.split.ident],
             "holdout": [[w.start_s, w.stop_s] for w in m.split.holdout],
             "holdout_excitation": dict(zip(("rms", "coherence"),
                                            (None if np.isnan(v) else v for v in holdout_excitation(m.split)))),
             "vaf_holdout": m.vaf_holdout, "tried": [[t, None if np.isnan(v) else v] for t, v in m.tried],
             **({"params": {k: float(v) for k, v in m.extra["params"].items()}} if "params" in m.extra else {}),
             **({"ci95": {k: [float(a), float(b)] for k, (a, b) in m.extra["ci95"].items()}}
                if "ci95" in m.extra else {}),
             **({"angle_loop": m.extra["angle_loop"]} if "angle_loop" in m.extra else {}),
             **({"controller_params_mapped": m.extra["controller_params_mapped"]}
                if "controller_params_mapped" in m.extra else {})}
    return save_model(path, m.model, vaf=[m.vaf_holdout], extra=extra, input=[m.input], output=[m.output],
                      units=dict(m.units))
