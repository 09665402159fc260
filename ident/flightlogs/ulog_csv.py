"""Reader for a folder of pyulog ``ulog2csv`` output: one CSV per topic instance plus the parameters.

``ulog2csv`` names each file ``<log name>_<topic>_<instance>.csv`` (or ``<topic>_<instance>.csv``) and keeps the
uORB field names and the microsecond ``timestamp``. Parameters come from ``parameters.octave`` or a
``name,value`` CSV as ``ulog_params`` writes them (``parameters.csv`` / ``params.csv``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from rotorlab.errors import DataError

from ._px4 import build_px4
from .flightlog import FlightLog
from .names import PX4_ROWS

__all__ = ["read_ulog_csv_dir", "KNOWN_TOPICS"]

# topics the PX4 builder reads besides the signal rows
KNOWN_TOPICS = sorted({r.topic for r in PX4_ROWS} | {"vehicle_status", "actuator_armed", "vehicle_land_detected",
                                                     "autotune_attitude_control_status", "vehicle_thrust_setpoint"})
_INSTANCE = re.compile(r"^(?P<stem>.+)_(?P<inst>\d+)\.csv$")


def _read_csv(path: Path) -> dict:
    import pyarrow.csv as pacsv

    try:
        table = pacsv.read_csv(path)
    except Exception as exc:  # pyarrow raises its own ArrowInvalid for malformed text
        raise DataError(f"{path}: not a readable CSV: {exc}") from None
    if "timestamp" not in table.column_names:
        raise DataError(f"{path}: no 'timestamp' column; expected ulog2csv output (columns: "
                        f"{', '.join(table.column_names[:8])})")
    return {c: np.asarray(table.column(c).to_numpy(zero_copy_only=False), dtype=float) for c in table.column_names}


def _read_params(folder: Path) -> tuple[dict, str]:
    octave = folder / "parameters.octave"
    if octave.exists():
        params, name = {}, None
        for line in octave.read_text().splitlines():
            if line.startswith("# name "):
                name = line[7:].strip()
            elif line.strip() and not line.startswith("#") and name is not None:
                try:
                    params[name] = float(line.strip())
                except ValueError:
                    raise DataError(f"{octave}: parameter {name}: expected a number, got {line.strip()!r}") from None
                name = None
        return params, octave.name
    for fname in ("parameters.csv", "params.csv"):
        p = folder / fname
        if p.exists():
            params = {}
            for k, line in enumerate(p.read_text().splitlines()):
                parts = [x.strip() for x in line.split(",")]
                if len(parts) < 2 or not parts[0]:
                    continue
                try:
                    params[parts[0]] = float(parts[1])
                except ValueError:
                    if k:  # a header row is allowed
                        raise DataError(f"{p}: line {k + 1}: expected name,value; got {line!r}") from None
            return params, fname
    return {}, ""


def read_ulog_csv_dir(path) -> FlightLog:
    """Read a ulog2csv folder into a :class:`~rotorlab.ident.flightlogs.flightlog.FlightLog`.

    Raises
    ------
    DataError
        No topic CSVs, a malformed CSV, or no rate-loop topics.

    Examples
    --------
    >>> from rotorlab.ident.flightlogs import read_flight_log
    >>> log = read_flight_log("log002_csv/")  # doctest: +SKIP
    """
    folder = Path(path)
    topics = {}
    for f in sorted(folder.glob("*.csv")):
        m = _INSTANCE.match(f.name)
        if not m:
            continue
        stem, inst = m["stem"], int(m["inst"])
        matches = [t for t in KNOWN_TOPICS if stem == t or stem.endswith("_" + t)]
        if not matches or inst != 0:
            continue
        topic = max(matches, key=len)
        topics.setdefault(topic, _read_csv(f))
    if not topics:
        raise DataError(f"{folder}: no ulog2csv topic files; expected files like vehicle_rates_setpoint_0.csv")
    params, pfile = _read_params(folder)
    log = build_px4(topics, params, str(folder), "ulog-csv")
    if not pfile:
        log.notes.append("no parameters.octave / parameters.csv: the controller's parameters are unknown")
    return log
