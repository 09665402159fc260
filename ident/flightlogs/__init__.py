"""Real flight logs in: PX4 ULog, ulog2csv folders and ArduPilot DataFlash, read into one :class:`FlightLog`.

:data:`READERS` is the registry of log formats (one module per format, walked by ``tests/test_flightlogs.py``);
:func:`read_flight_log` picks the reader from the path. The topic and field names of every autopilot version
live in one table, :mod:`~rotorlab.ident.flightlogs.names`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rotorlab.errors import DataError, UnknownNameError

from .dataflash import read_dataflash
from .flightlog import FlightLog, Interval, Record, Series, time_base_s
from .ulog import read_ulog
from .ulog_csv import read_ulog_csv_dir

__all__ = ["Reader", "READERS", "read_flight_log", "detect_format", "FlightLog", "Interval", "Record", "Series",
           "time_base_s"]


@dataclass(frozen=True)
class Reader:
    """A flight-log format: its reader, the file suffixes (or ``"/"`` for a folder) it claims, a description."""

    name: str
    read: Callable[..., FlightLog]
    suffixes: tuple[str, ...]
    description: str


READERS: dict[str, Reader] = {r.name: r for r in (
    Reader("ulog", read_ulog, (".ulg",), "PX4 ULog (pyulog)"),
    Reader("ulog-csv", read_ulog_csv_dir, ("/",), "folder of pyulog ulog2csv output"),
    Reader("dataflash", read_dataflash, (".bin", ".log"), "ArduPilot DataFlash binary or text (pymavlink DFReader)"),
)}


def detect_format(path) -> str:
    """The :data:`READERS` key for ``path`` (by suffix; a folder is a ulog2csv export)."""
    p = Path(path)
    if p.is_dir():
        return "ulog-csv"
    for r in READERS.values():
        if p.suffix.lower() in r.suffixes:
            return r.name
    raise DataError(f"{p}: unknown flight-log format {p.suffix!r}; expected "
                    + ", ".join(f"{'a folder' if s == '/' else s} ({r.description})"
                                for r in READERS.values() for s in r.suffixes))


def read_flight_log(path, fmt: str | None = None, **kwargs) -> FlightLog:
    """Read a flight log with the reader of ``fmt`` (detected from the path when None).

    Examples
    --------
    >>> log = read_flight_log("flight.ulg")  # doctest: +SKIP
    >>> log.axes  # doctest: +SKIP
    ['roll', 'pitch', 'yaw']
    """
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: no such file or folder")
    name = fmt or detect_format(p)
    if name not in READERS:
        raise UnknownNameError("flight-log format", name, READERS)
    return READERS[name].read(p, **kwargs)
