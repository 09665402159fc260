"""PX4 topics -> :class:`FlightLog`, shared by the ULog reader and the ulog2csv-folder reader.

Both readers hand over the same thing: ``topics[name] = {field: ndarray}`` (instance 0 of each topic, the
``timestamp`` field in microseconds as uORB defines it) and the parameters.
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import DataError

from .flightlog import FlightLog, Interval, Series, intervals_where, labelled_intervals, quat_to_euler, time_base_s
from .names import AXES, PX4_AUTOTUNE_NEW_LAYOUT, PX4_AUTOTUNE_STATES, PX4_NAV_STATES, SIGNAL_UNITS, SIGNALS, rows_for

ARMING_STATE_ARMED = 2  # vehicle_status.arming_state (msg/VehicleStatus.msg), the same number in every release


def release_string(ver_sw_release) -> str:
    """``ver_sw_release`` (0xMMmmppTT) as ``"v1.15.0"``; "" when the log does not say (0 or absent)."""
    try:
        v = int(ver_sw_release)
    except (TypeError, ValueError):
        return ""
    if v <= 0:
        return ""
    return f"v{(v >> 24) & 0xFF}.{(v >> 16) & 0xFF}.{(v >> 8) & 0xFF}"


def _time(topics, name, path, events=False):
    return time_base_s(topics[name]["timestamp"], "us", f"{path}: {name}.timestamp", events=events)


def build_px4(topics: dict, params: dict, path: str, fmt: str, version: str = "") -> FlightLog:
    """A :class:`FlightLog` from PX4 topics; rows of :mod:`~rotorlab.ident.flightlogs.names` pick the fields."""
    log = FlightLog(path=str(path), format=fmt, autopilot="px4", version=version, params=dict(params))
    for signal in SIGNALS:
        for row in rows_for("px4", signal):
            d = topics.get(row.topic)
            if d is None or not all(f in d for f in row.fields) or len(d["timestamp"]) < 2:
                continue
            t = _time(topics, row.topic, path)
            if row.kind == "quaternion":
                vals = quat_to_euler(np.column_stack([d[f] for f in row.fields]))
                unit_src = "quaternion"
            else:
                vals = np.column_stack([np.asarray(d[f], float) * row.scale for f in row.fields])
                unit_src = row.unit
            for k, axis in enumerate(AXES):
                src = f"{row.topic}.{'q' if row.kind == 'quaternion' else row.fields[k]} ({unit_src})"
                log.signals[axis][signal] = Series(t, vals[:, k], SIGNAL_UNITS[signal], src)
            if row is not rows_for("px4", signal)[0]:
                log.notes.append(f"{signal} from {row.topic} ({row.versions})")
            break
    rate = log.signals["roll"].get("rate")
    if rate is not None and rate.source.startswith("sensor_gyro.") and params.get("SENS_BOARD_ROT", 0) != 0:
        # the raw gyro topic is in the sensor's frame; a rotated board swaps or flips its axes
        raise DataError(f"{path}: the measured rate comes from sensor_gyro (sensor frame) and SENS_BOARD_ROT = "
                        f"{params['SENS_BOARD_ROT']}; expected SENS_BOARD_ROT = 0 (no board rotation) or a body-frame "
                        "rate topic (vehicle_angular_velocity, sensor_combined)")
    if not log.axes:
        missing = [s for s in ("rate_sp", "rate") if s not in log.signals["roll"]]
        looked = "; ".join(f"{s}: " + ", ".join(f"{r.topic}.{r.fields[0]}" for r in rows_for("px4", s))
                           for s in missing)
        raise DataError(f"{path}: no rate-loop signals; looked for {looked}; got topics "
                        f"{', '.join(sorted(topics)) or 'none'} (a log cut before its data, or another logger profile?)")
    t_end = max(float(s.t_s[-1]) for a in AXES for s in log.signals[a].values())
    st = topics.get("vehicle_status")
    if st is not None and "arming_state" in st and len(st["timestamp"]):
        ts = _time(topics, "vehicle_status", path, events=True)
        log.armed = intervals_where(ts, np.asarray(st["arming_state"]) == ARMING_STATE_ARMED, "armed", t_end)
        if "nav_state" in st:
            log.modes = labelled_intervals(ts, [PX4_NAV_STATES.get(int(v), f"nav_state {int(v)}")
                                                for v in st["nav_state"]], t_end)
    elif "actuator_armed" in topics:
        ts = _time(topics, "actuator_armed", path, events=True)
        log.armed = intervals_where(ts, np.asarray(topics["actuator_armed"]["armed"]) > 0, "armed", t_end)
    land = topics.get("vehicle_land_detected")
    thr = _thrust(topics, path)
    by_thrust = airborne_from_thrust(*thr, log.armed) if thr is not None else None
    if land is not None and "landed" in land and len(land["timestamp"]):
        ts = _time(topics, "vehicle_land_detected", path, events=True)
        log.airborne = and_intervals(intervals_where(ts, np.asarray(land["landed"]) == 0, "airborne", t_end), log.armed)
        log.airborne_source = "vehicle_land_detected.landed == 0 while armed"
        if by_thrust is not None:
            log.airborne = and_intervals(log.airborne, by_thrust[0]) if by_thrust[0] else []
            log.airborne_source += " and " + by_thrust[1]
    elif by_thrust is not None:
        log.airborne, log.airborne_source = by_thrust[0], "armed and " + by_thrust[1]
    at = topics.get("autotune_attitude_control_status")
    if at is not None and "state" in at and len(at["timestamp"]):
        ts = _time(topics, "autotune_attitude_control_status", path, events=True)
        new = version and tuple(int(x) for x in version[1:].split(".")[:2]) >= PX4_AUTOTUNE_NEW_LAYOUT
        layout = "v1.17" if new else "legacy"
        for axis, states in PX4_AUTOTUNE_STATES[layout].items():
            log.excitation += intervals_where(ts, np.isin(np.asarray(at["state"]), states), axis, t_end)
        log.excitation.sort(key=lambda i: i.start_s)
    return log


def and_intervals(a: list, b: list) -> list:
    """Intersection of two interval lists (``b`` empty: ``a`` unchanged, the log does not say)."""
    if not b:
        return a
    out = []
    for x in a:
        for y in b:
            lo, hi = max(x.start_s, y.start_s), min(x.stop_s, y.stop_s)
            if hi > lo:
                out.append(Interval(lo, hi, x.label))
    return out


def _thrust(topics, path):
    """(t_s, thrust >= 0) from the first thrust signal the log has, or None."""
    for topic, fld, sign in (("vehicle_thrust_setpoint", "xyz[2]", -1.0), ("actuator_controls_0", "control[3]", 1.0),
                             ("vehicle_rates_setpoint", "thrust", 1.0),
                             ("vehicle_rates_setpoint", "thrust_body[2]", -1.0)):
        d = topics.get(topic)
        if d is not None and fld in d and len(d["timestamp"]) > 1:
            return _time(topics, topic, path), sign * np.asarray(d[fld], float), f"{topic}.{fld}"
    return None


def airborne_from_thrust(t_s, thrust, source, armed, min_s: float = 1.0):
    """Airborne intervals where there is no land detector: armed and thrust at least half its armed median.

    A multirotor on the ground idles its motors far below hover thrust; half the median of the armed,
    non-idle thrust separates the two on every log this was tried on. Intervals shorter than ``min_s`` go.
    """
    t_s, thrust = np.asarray(t_s, float), np.asarray(thrust, float)
    on = np.ones_like(t_s, bool) if not armed else np.zeros_like(t_s, bool)
    for i in armed:
        on |= (t_s >= i.start_s) & (t_s <= i.stop_s)
    active = on & (thrust > 0.05)
    if not active.any():
        return [], f"{source} never above idle while armed"
    level = 0.5 * float(np.median(thrust[active]))
    iv = [i for i in intervals_where(t_s, active & (thrust >= level), "airborne") if i.duration_s >= min_s]
    return iv, f"{source} >= {level:.3g} (half its armed median)"
