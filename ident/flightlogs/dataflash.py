"""ArduPilot DataFlash (.bin binary, .log text) reader, through pymavlink's DFReader."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rotorlab.errors import DataError

from ._px4 import airborne_from_thrust, and_intervals
from .flightlog import FlightLog, Interval, Series, intervals_where, labelled_intervals, time_base_s
from .names import ARDUCOPTER_MODES, ARDUPILOT_SID_AXES, AXES, SIGNAL_UNITS, SIGNALS, rows_for

__all__ = ["read_dataflash", "EV_ARMED", "EV_DISARMED", "EV_LAND_COMPLETE", "EV_NOT_LANDED"]

# ArduCopter LogEvent ids (ArduCopter/defines.h, AP_Logger LogEvent): the armed state and the land detector
EV_ARMED, EV_DISARMED, EV_LAND_COMPLETE, EV_NOT_LANDED = 10, 11, 18, 28
_WANTED = {"RATE", "ATT", "MODE", "EV", "PARM", "SIDS", "SIDD", "CTUN", "MSG"}


def _collect(path: Path):
    from pymavlink import DFReader

    text = path.suffix.lower() == ".log"
    try:
        reader = DFReader.DFReader_text(str(path)) if text else DFReader.DFReader_binary(str(path))
    except Exception as exc:  # DFReader raises bare Exceptions, struct and index errors on malformed files
        raise DataError(f"{path}: pymavlink cannot read it as a DataFlash {'text' if text else 'binary'} log: "
                        f"{exc}") from None
    cols, params, version = {}, {}, ""
    while True:
        try:
            m = reader.recv_match(type=list(_WANTED))
        except Exception as exc:
            raise DataError(f"{path}: DataFlash parse error after {sum(len(v) for v in cols.values())} messages: "
                            f"{exc}") from None
        if m is None:
            break
        typ = m.get_type()
        if typ == "PARM":
            params.setdefault(m.Name, float(m.Value))
            continue
        if typ == "MSG" and not version and ("Copter" in m.Message or "Plane" in m.Message):
            version = m.Message.strip()
        cols.setdefault(typ, []).append(m.to_dict())
    return cols, params, version


def _time(rows, path, typ, events=False):
    first = rows[0]
    if "TimeUS" in first:
        return time_base_s([r["TimeUS"] for r in rows], "us", f"{path}: {typ}.TimeUS", events=events)
    if "TimeMS" in first:
        return time_base_s([r["TimeMS"] for r in rows], "ms", f"{path}: {typ}.TimeMS", events=events)
    raise DataError(f"{path}: {typ} has no TimeUS or TimeMS field; expected one (fields: {', '.join(first)})")


def read_dataflash(path) -> FlightLog:
    """Read a DataFlash log into a :class:`~rotorlab.ident.flightlogs.flightlog.FlightLog`.

    Rates and angles come from ``RATE`` and ``ATT`` (deg/s and deg in the log, rad/s and rad here), modes from
    ``MODE``, armed and airborne from the ``EV`` events (ARMED/DISARMED, NOT_LANDED/LAND_COMPLETE; a thrust
    threshold on ``CTUN.ThO`` when the log has no land events), excitation from ``SIDD`` (axis from ``SIDS.Ax``),
    parameters from ``PARM``.

    Raises
    ------
    DataError
        Unreadable file, no RATE messages, or a time base that is not microseconds/milliseconds.

    Examples
    --------
    >>> from rotorlab.ident.flightlogs import read_flight_log
    >>> log = read_flight_log("00000012.BIN")  # doctest: +SKIP
    """
    path = Path(path)
    cols, params, version = _collect(path)
    log = FlightLog(path=str(path), format="dataflash", autopilot="ardupilot", version=version, params=params)
    for signal in SIGNALS:
        for row in rows_for("ardupilot", signal):
            rows = cols.get(row.topic)
            if not rows or not all(f in rows[0] for f in row.fields):
                continue
            t = _time(rows, path, row.topic)
            for k, axis in enumerate(AXES):
                v = np.array([r[row.fields[k]] for r in rows], float) * row.scale
                log.signals[axis][signal] = Series(t, v, SIGNAL_UNITS[signal],
                                                   f"{row.topic}.{row.fields[k]} ({row.unit})")
            break
    if "RATE" not in cols:
        raise DataError(f"{path}: no RATE messages; expected RATE (RDes/R/ROut ...) for the rate loop (enable the "
                        f"attitude logging bits of LOG_BITMASK); got {', '.join(sorted(cols)) or 'no messages'}")
    if not log.axes:
        raise DataError(f"{path}: RATE has fields {', '.join(cols['RATE'][0])}; expected RDes/R/ROut or "
                        "RllDes/Rll/RllOut")
    t_end = max(float(s.t_s[-1]) for a in AXES for s in log.signals[a].values())
    if "MODE" in cols:
        tm = _time(cols["MODE"], path, "MODE", events=True)
        num = [r.get("ModeNum", r.get("Mode")) for r in cols["MODE"]]
        log.modes = labelled_intervals(tm, [ARDUCOPTER_MODES.get(int(n), f"mode {n}") for n in num], t_end)
    ev = cols.get("EV", [])
    if ev:
        te = _time(ev, path, "EV", events=True)
        ids = np.array([r["Id"] for r in ev])
        log.armed = _event_intervals(te, ids, EV_ARMED, EV_DISARMED, "armed", t_end)
        if np.isin(ids, (EV_NOT_LANDED, EV_LAND_COMPLETE)).any():
            log.airborne = and_intervals(_event_intervals(te, ids, EV_NOT_LANDED, EV_LAND_COMPLETE, "airborne", t_end),
                                         log.armed)
            log.airborne_source = "EV NOT_LANDED .. LAND_COMPLETE while armed"
    if "CTUN" in cols and "ThO" in cols["CTUN"][0]:
        # the land detector of Copter 3.4 reports NOT_LANDED at spool-up, long before lift-off: thrust decides too
        tc = _time(cols["CTUN"], path, "CTUN")
        iv, src = airborne_from_thrust(tc, np.array([r["ThO"] for r in cols["CTUN"]], float), "CTUN.ThO", log.armed)
        log.airborne = and_intervals(log.airborne, iv) if log.airborne_source and iv else iv
        log.airborne_source = f"{log.airborne_source} and {src}" if log.airborne_source else f"armed and {src}"
    if "SIDD" in cols:
        ts = _time(cols["SIDD"], path, "SIDD")
        sids = cols.get("SIDS", [])
        t_sids = _time(sids, path, "SIDS", events=True) if sids else np.zeros(0)
        # SIDD is written every loop while the chirp runs: a gap of more than 0.5 s ends one excitation window,
        # whose axis is that of the last SIDS (the settings logged when SYSID mode starts) before it
        gaps = np.flatnonzero(np.diff(ts) > 0.5)
        for a, b in zip(np.r_[0, gaps + 1], np.r_[gaps, len(ts) - 1]):
            before = np.flatnonzero(t_sids <= ts[a] + 1e-9)
            ax = int(sids[before[-1]]["Ax"]) if before.size else 0
            axis = ARDUPILOT_SID_AXES.get(ax)
            if axis is None:
                log.notes.append(f"SIDD at {ts[a]:.1f} s: SIDS.Ax = {ax} names no roll/pitch/yaw axis")
            else:
                log.excitation.append(Interval(float(ts[a]), float(ts[b]), axis))
    return log


def _event_intervals(t, ids, on_id, off_id, label, t_end):
    keep = np.isin(ids, (on_id, off_id))
    return intervals_where(t[keep], ids[keep] == on_id, label, t_end)
