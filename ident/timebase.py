"""The time base of a log: a time column read in seconds, or refused -- never used in another unit.

:func:`time_in_seconds` is the one rule every log reader applies (CSV and Parquet in
:mod:`rotorlab.ident.logs`; a foreign-format reader calls it with what its format declares). The unit of a time
column comes, in this order of precedence, from

1. the column's type: an Arrow/numpy ``timestamp``/``datetime64`` or ``duration``/``timedelta64`` carries its
   unit (s, ms, us, ns), which is used exactly;
2. an explicit unit from the caller (``rotorlab ident --time-unit``): ``s``, ``ms``, ``us``, ``ns`` -- taken as
   given, the user's word overrides the file -- or ``auto``, which accepts the detected unit below when exactly
   one unit fits;
3. the file's declaration (a Parquet log's ``units`` metadata for ``t``), taken when it gives a plausible
   logging rate and refused otherwise;
4. nothing: the column is taken as seconds when it gives a plausible logging rate.

A logging rate is plausible between :data:`RATE_HZ` (2 Hz to 100 kHz: the median step 10 us ... 0.5 s). A column
whose median step is not a plausible step in seconds (microsecond time stamps at 250 Hz have a step of 4000) is
refused with the units that would make it plausible (for ``auto``: a rate within :data:`DETECT_RATE_HZ`, 2 Hz to
10 kHz, where the candidate units never overlap for the usual flight-log rates 10 Hz ... 2 kHz).

A column converted from another unit starts at 0 s (its first stamp is subtracted in the file's unit, exactly
for integer stamps, so 64-bit epoch stamps keep their sub-microsecond steps); a column in seconds keeps its
origin.

Examples
--------
>>> import numpy as np
>>> t_s, unit = time_in_seconds(np.arange(5) * 4000, "us")
>>> float(t_s[1]), unit
(0.004, 'us')
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import DataError
from rotorlab.units import TIME_UNITS, canonical

__all__ = ["RATE_HZ", "DETECT_RATE_HZ", "time_in_seconds"]

#: logging rates (Hz) a time column is accepted at without an explicit unit
RATE_HZ = (2.0, 100_000.0)
#: rates (Hz) a candidate unit must give for the detection (``auto``) to pick it
DETECT_RATE_HZ = (2.0, 10_000.0)


def _median_step(raw: np.ndarray) -> float:
    d = np.diff(raw[: min(raw.size, 100_001)].astype(float))  # a long log's median is its first 100 000 steps'
    return float(np.median(d)) if d.size else float("nan")


def _plausible(step_s: float, band) -> bool:
    return step_s > 0 and band[0] <= 1.0 / step_s <= band[1]


def _fits(step: float, band) -> list[tuple[str, float]]:
    """``(unit, rate_hz)`` for every time unit that makes ``step`` a logging rate within ``band``."""
    return [(u, 1.0 / (step * f)) for u, f in TIME_UNITS.items() if _plausible(step * f, band)]


def _refuse(source, column, raw, step, what) -> DataError:
    fits = _fits(step, DETECT_RATE_HZ)
    why = (f"it fits {' or '.join(f'{u} ({rate:.4g} Hz)' for u, rate in fits)}" if fits else
           f"no time unit makes it a logging rate of {DETECT_RATE_HZ[0]:g} ... {DETECT_RATE_HZ[1]:g} Hz")
    hint = f"pass --time-unit {fits[0][0]}" if len(fits) == 1 else "pass --time-unit UNIT"
    return DataError(f"{source}: time column '{column}': {what}; expected time stamps in s at a logging rate of "
                     f"{RATE_HZ[0]:g} ... {RATE_HZ[1]:g} Hz (a median step of {1 / RATE_HZ[1]:g} ... "
                     f"{1 / RATE_HZ[0]:g} s); got a median step of {step:.6g} over {raw.size} samples (span "
                     f"{float(raw[-1]) - float(raw[0]):.6g}): {why}; {hint} (s, ms, us, ns or auto; in Python "
                     "load_log(..., time_unit=UNIT))")


def time_in_seconds(raw, unit: str | None = None, *, declared: str | None = None, source: str = "log",
                    column: str = "t") -> tuple[np.ndarray, str]:
    """The time column ``raw`` in seconds, by the rule of the module docstring.

    Parameters
    ----------
    raw : array_like
        The column as stored: numbers (int or float), ``datetime64`` or ``timedelta64``.
    unit : str, optional
        Explicit unit (``s``, ``ms``, ``us``, ``ns`` or ``auto``): overrides ``declared``.
    declared : str, optional
        The unit the file states for the column (Parquet ``units`` metadata); checked for plausibility.
    source, column : str
        The file and the column's name in it, for messages.

    Returns
    -------
    t_s : ndarray of float
        Time in s (strictly increasing is checked by the caller).
    unit : str
        The unit the column was read in (canonical spelling).

    Raises
    ------
    DataError
        An unknown unit, a declared unit that gives an implausible rate, or a column without a unit that is not
        plausible in seconds (naming the file, the column, the expected and the found median step, and the
        units that would fit).
    """
    raw = np.asarray(raw)
    if unit is not None and unit != "auto" and canonical(unit) not in TIME_UNITS:
        raise DataError(f"{source}: time column '{column}': unknown time unit {unit!r}; expected one of "
                        f"{', '.join(TIME_UNITS)} or auto")
    if raw.dtype.kind in "mM":  # the type carries the unit
        typed, _ = np.datetime_data(raw.dtype)
        if typed not in TIME_UNITS:
            raise DataError(f"{source}: time column '{column}': time stamps in units of {typed!r}; expected "
                            f"s, ms, us or ns stamps")
        if unit not in (None, "auto") and canonical(unit) != typed:
            raise DataError(f"{source}: time column '{column}': its type says {typed} time stamps; "
                            f"got --time-unit {unit}; leave the option out")
        counts = raw.view(np.int64)
        return (counts - counts[0]).astype(float) * TIME_UNITS[typed], typed
    if raw.size == 0:
        return raw.astype(float), "s"
    step = _median_step(raw)
    if unit not in (None, "auto"):
        told = canonical(unit)  # the user's word overrides the file's
    elif unit is None and declared is not None:
        told = canonical(declared)
        if told not in TIME_UNITS:
            raise DataError(f"{source}: time column '{column}': the file declares the unit {declared!r}; expected "
                            f"one of {', '.join(TIME_UNITS)} (override with --time-unit)")
        if not _plausible(step * TIME_UNITS[told], RATE_HZ):
            raise _refuse(source, column, raw, step, f"the file declares it in {declared!r}")
    elif _plausible(step, RATE_HZ):
        told = "s"
    else:
        fits = _fits(step, DETECT_RATE_HZ)
        if unit != "auto" or len(fits) != 1:
            raise _refuse(source, column, raw, step, "no unit given" if unit is None else
                          "auto: not exactly one time unit fits")
        told = fits[0][0]
    if told == "s":
        return raw.astype(float), "s"
    if raw.dtype.kind in "iu":
        return (raw.astype(np.int64) - np.int64(raw[0])).astype(float) * TIME_UNITS[told], told
    return (raw.astype(float) - float(raw[0])) * TIME_UNITS[told], told
