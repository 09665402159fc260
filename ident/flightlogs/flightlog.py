"""The flight-log object every reader returns, the time-base check, and resampling to one uniform rate.

A :class:`FlightLog` holds, per axis (roll, pitch, yaw), the autopilot's signals as they were logged (each on its
own time stamps, already in the project's units: rad, rad/s, s, the rate-loop output normalised), plus flight
modes, armed and airborne intervals, system-identification excitation windows and the autopilot's parameters.
:meth:`FlightLog.record` brings the signals one identification needs onto one uniform grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal as sig

from rotorlab.errors import DataError

from .names import AXES

__all__ = ["Series", "Interval", "FlightLog", "Record", "time_base_s", "quat_to_euler", "TIME_UNITS"]

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def time_base_s(t_raw, unit: str | None, source: str, *, min_rate_hz: float = 0.05,
                max_rate_hz: float = 20000.0, events: bool = False) -> np.ndarray:
    """Time stamps in seconds from raw stamps in ``unit``, or the unit detected when ``unit`` is None.

    The one place a flight log's time base is decided. A declared unit (ULog and DataFlash declare
    microseconds) is checked: the median sample rate must lie within ``[min_rate_hz, max_rate_hz]`` and the
    stamps must not run backwards; otherwise the log is refused. Without a declared unit exactly one of s, ms,
    us, ns must give a plausible rate (1 Hz to ``max_rate_hz``) or the log is refused: a microsecond stamp read
    as seconds (a 250 Hz log seen as one sample every 4000 s) is never used silently.

    Parameters
    ----------
    t_raw : array_like
        Raw stamps, increasing.
    unit : {"s", "ms", "us", "ns"} or None
    source : str
        File and column, for the message.
    events : bool
        Stamps of sparse events (mode changes, arming): a declared unit is taken without the rate check (the
        signals' stamps of the same log are checked), one stamp is enough.

    Returns
    -------
    ndarray of float, seconds

    Raises
    ------
    DataError
        Implausible, ambiguous or decreasing stamps.

    Examples
    --------
    >>> time_base_s([1_000_000, 1_004_000, 1_008_000], "us", "log.ulg:timestamp")[:2]
    array([1.   , 1.004])
    """
    t = np.asarray(t_raw, dtype=float)
    if events and unit in TIME_UNITS and t.size >= 1:
        if np.any(np.diff(t) < 0):
            raise DataError(f"{source}: event time stamps run backwards; expected increasing stamps")
        return t * TIME_UNITS[unit]
    if t.size < 2:
        raise DataError(f"{source}: expected at least 2 time stamps, got {t.size}")
    d = np.diff(t)
    if np.any(d < 0):
        i = int(np.argmax(d < 0))
        raise DataError(f"{source}: time stamps run backwards at sample {i + 1} ({t[i]:.9g} -> {t[i + 1]:.9g}); "
                        "expected increasing stamps")
    med = float(np.median(d[d > 0])) if np.any(d > 0) else 0.0
    if med <= 0:
        raise DataError(f"{source}: all time stamps are equal ({t[0]:.9g}); expected increasing stamps")
    if unit is not None:
        if unit not in TIME_UNITS:
            raise DataError(f"{source}: unknown time unit {unit!r}; expected one of {sorted(TIME_UNITS)}")
        rate = 1.0 / (med * TIME_UNITS[unit])
        if not min_rate_hz <= rate <= max_rate_hz:
            raise DataError(f"{source}: time stamps declared in {unit} give a median sample rate of {rate:.4g} Hz; "
                            f"expected {min_rate_hz:g} to {max_rate_hz:g} Hz (is the time base another unit?)")
        return t * TIME_UNITS[unit]
    fits = [u for u, s in TIME_UNITS.items() if 1.0 <= 1.0 / (med * s) <= max_rate_hz]
    if len(fits) != 1:
        raise DataError(f"{source}: cannot tell the time unit: a median step of {med:.6g} gives a plausible rate "
                        f"(1 to {max_rate_hz:g} Hz) in {fits or 'no unit'}; expected exactly one of "
                        f"{sorted(TIME_UNITS)}; state the unit")
    return t * TIME_UNITS[fits[0]]


def quat_to_euler(q) -> np.ndarray:
    """Roll, pitch, yaw (rad, ZYX Euler angles) from unit quaternions ``(N, 4)`` ordered w, x, y, z (PX4's
    ``q[0..3]``).

    Examples
    --------
    >>> quat_to_euler([[np.cos(0.25), np.sin(0.25), 0.0, 0.0]]).round(6)  # 0.5 rad about x
    array([[0.5, 0. , 0. ]])
    """
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.column_stack([roll, pitch, yaw])


@dataclass(frozen=True)
class Series:
    """One logged signal: time stamps (s) and values in ``unit``, and where it came from (``topic.field``)."""

    t_s: np.ndarray
    values: np.ndarray
    unit: str
    source: str

    @property
    def rate_hz(self) -> float:
        """Median sample rate, Hz."""
        d = np.diff(self.t_s)
        return float(1.0 / np.median(d[d > 0]))


@dataclass(frozen=True)
class Interval:
    """A time interval ``[start_s, stop_s]`` with a label (mode name, axis, ...)."""

    start_s: float
    stop_s: float
    label: str = ""

    @property
    def duration_s(self) -> float:
        return self.stop_s - self.start_s


def intervals_where(t_s, flag, label: str = "", t_end_s: float | None = None) -> list[Interval]:
    """Intervals where a step-wise boolean ``flag`` sampled at ``t_s`` holds (each value holds until the next
    sample; the last until ``t_end_s``)."""
    t = np.asarray(t_s, float)
    f = np.asarray(flag, bool)
    if t.size == 0:
        return []
    end = t[-1] if t_end_s is None else max(t_end_s, t[-1])
    out, start = [], None
    for k in range(t.size):
        if f[k] and start is None:
            start = t[k]
        elif not f[k] and start is not None:
            out.append(Interval(float(start), float(t[k]), label))
            start = None
    if start is not None:
        out.append(Interval(float(start), float(end), label))
    return out


def labelled_intervals(t_s, labels, t_end_s: float) -> list[Interval]:
    """Intervals of constant label from a step-wise label sequence (mode changes)."""
    out = []
    for k, (t0, lab) in enumerate(zip(t_s, labels)):
        t1 = t_s[k + 1] if k + 1 < len(t_s) else t_end_s
        if out and out[-1].label == lab:
            out[-1] = Interval(out[-1].start_s, float(t1), lab)
        elif t1 > t0:
            out.append(Interval(float(t0), float(t1), str(lab)))
    return out


@dataclass
class Record:
    """Signals of one axis on one uniform grid, ready for identification.

    Attributes
    ----------
    axis : str
    t_s : ndarray
        Uniform time stamps, s.
    dt : float
        Sample time, s.
    data : dict of str -> ndarray
        ``rate_sp``, ``rate``, ``rate_out`` as asked, in :data:`~rotorlab.ident.flightlogs.names.SIGNAL_UNITS`.
    units : dict of str -> str
    sources : dict of str -> str
        ``topic.field`` each signal came from.
    """

    axis: str
    t_s: np.ndarray
    dt: float
    data: dict
    units: dict
    sources: dict

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass
class FlightLog:
    """A flight log read into the project's conventions.

    Attributes
    ----------
    path : str
    format : str
        Reader name (a key of :data:`rotorlab.ident.flightlogs.READERS`).
    autopilot : {"px4", "ardupilot"}
    version : str
        Software version as the log states it ("" when it does not).
    signals : dict
        ``signals[axis][signal]`` -> :class:`Series` (rad, rad/s, normalised output); missing signals absent.
    modes : list of Interval
        Flight modes over time (label = mode name).
    armed, airborne : list of Interval
    airborne_source : str
        How airborne was decided (land detector, events, or a thrust threshold), for the report.
    excitation : list of Interval
        Excitation windows the autopilot logged (label = axis).
    params : dict of str -> float
        The autopilot's parameters at the start of the log.
    notes : list of str
        What the reader noticed (fallback topics, truncation, dropped stamps).

    Examples
    --------
    >>> from rotorlab.ident.flightlogs import read_flight_log
    >>> log = read_flight_log("flight.ulg")  # doctest: +SKIP
    >>> rec = log.record("roll", ("rate_sp", "rate"))  # doctest: +SKIP
    >>> rec.dt, rec.units  # doctest: +SKIP
    (0.004, {'rate_sp': 'rad/s', 'rate': 'rad/s'})
    """

    path: str
    format: str
    autopilot: str
    version: str = ""
    signals: dict = field(default_factory=lambda: {a: {} for a in AXES})
    modes: list = field(default_factory=list)
    armed: list = field(default_factory=list)
    airborne: list = field(default_factory=list)
    airborne_source: str = ""
    excitation: list = field(default_factory=list)
    params: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def axes(self) -> list[str]:
        """Axes with a rate set-point and a measured rate."""
        return [a for a in AXES if {"rate_sp", "rate"} <= set(self.signals[a])]

    def series(self, axis: str, name: str) -> Series:
        """The signal ``name`` of ``axis``; DataError naming what the log lacks."""
        if axis not in AXES:
            raise DataError(f"{self.path}: unknown axis {axis!r}; expected one of {', '.join(AXES)}")
        s = self.signals[axis].get(name)
        if s is None:
            have = ", ".join(sorted(self.signals[axis])) or "none"
            raise DataError(f"{self.path}: no {name} for the {axis} axis in this {self.autopilot} log "
                            f"(signals found: {have}); see names.py for the topics and fields looked for")
        return s

    def param(self, name: str) -> float:
        """Parameter ``name``; DataError when the log does not carry it."""
        if name not in self.params:
            raise DataError(f"{self.path}: parameter {name} is not in the log; expected it among the "
                            f"{len(self.params)} parameters logged")
        return float(self.params[name])

    def airborne_time_s(self) -> float:
        return float(sum(i.duration_s for i in self.airborne))

    def record(self, axis: str, names=("rate_sp", "rate", "rate_out"), rate_hz: float | None = None) -> Record:
        """The signals ``names`` of ``axis`` on one uniform grid over the time all of them cover.

        The grid rate defaults to the slowest signal's median rate (nothing is invented between samples). A
        faster signal is first interpolated onto a uniform grid at its own rate, low-passed zero-phase
        (4th-order Butterworth, ``scipy.signal.sosfiltfilt``) at 0.4 times the target rate, then sampled:
        no content above the new Nyquist frequency folds down. A slower or equal one is interpolated linearly.
        """
        ss = {n: self.series(axis, n) for n in names}
        if rate_hz is None:
            rate_hz = min(s.rate_hz for s in ss.values())
        t0 = max(s.t_s[0] for s in ss.values())
        t1 = min(s.t_s[-1] for s in ss.values())
        if t1 - t0 < 20.0 / rate_hz:
            raise DataError(f"{self.path}: the {axis} signals {', '.join(names)} overlap for {max(t1 - t0, 0):.3g} s; "
                            "expected them logged over the same flight")
        dt = 1.0 / rate_hz
        t = t0 + dt * np.arange(int(np.floor((t1 - t0) / dt)) + 1)
        data = {n: resample(s.t_s, s.values, t, rate_hz) for n, s in ss.items()}
        return Record(axis, t, dt, data, {n: s.unit for n, s in ss.items()}, {n: s.source for n, s in ss.items()})


def resample(t_s, x, t_new, rate_hz: float) -> np.ndarray:
    """``x`` sampled at ``t_s`` onto ``t_new`` (uniform at ``rate_hz``), anti-alias filtered when ``x`` is faster.

    See :meth:`FlightLog.record`.

    Examples
    --------
    >>> t = np.arange(0, 2, 0.002)
    >>> bool(resample(t, np.sin(2 * np.pi * 200 * t), np.arange(0.5, 1.5, 0.004), 250.0).std() < 0.01)
    True
    """
    t_s, x = np.asarray(t_s, float), np.asarray(x, float)
    d = np.diff(t_s)
    own = 1.0 / float(np.median(d[d > 0]))
    if own > 1.25 * rate_hz:
        tu = np.arange(t_s[0], t_s[-1], 1.0 / own)
        xu = np.interp(tu, t_s, x)
        sos = sig.butter(4, 0.4 * rate_hz, fs=own, output="sos")
        if len(xu) > 3 * 2 * (sos.shape[0] + 1):
            xu = sig.sosfiltfilt(sos, xu)
        return np.interp(t_new, tu, xu)
    return np.interp(t_new, t_s, x)
