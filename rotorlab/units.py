"""Units of user data and models: the few rotorlab converts between, with their exact factors.

A unit is one of the spellings below (aliases in brackets map to the canonical one):

========================  ==============  =====================================================================
quantity                  canonical       factor to the quantity's base unit
========================  ==============  =====================================================================
time                      ``s``           1; ``ms`` 1e-3, ``us`` (``µs``) 1e-6, ``ns`` 1e-9
angle                     ``rad``         1; ``deg`` pi/180
angular rate              ``rad/s``       1; ``deg/s`` (``dps``) pi/180
command                   ``1``           1 (normalised command, ``[-1, 1]``); ``%`` 0.01 (1 = 100 %)
========================  ==============  =====================================================================

The table is written here rather than taken from a units library (pint): rotorlab converts only between
these, each conversion is one exact factor, and a unit outside the table must be refused, not interpreted.
Any other unit string (``m/s``, ``N``) is kept as written and only ever compared for equality.

Examples
--------
>>> from rotorlab.units import factor
>>> round(factor("rad/s", "deg/s"), 4)
57.2958
>>> factor("1", "%")
100.0
>>> factor("%", "deg/s") is None
True
"""

from __future__ import annotations

import math

__all__ = ["UNITS", "canonical", "factor", "quantity", "TIME_UNITS"]

#: canonical unit -> (quantity, factor to the quantity's base unit)
UNITS = {
    "s": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6), "ns": ("time", 1e-9),
    "rad": ("angle", 1.0), "deg": ("angle", math.pi / 180.0),
    "rad/s": ("angular rate", 1.0), "deg/s": ("angular rate", math.pi / 180.0),
    "1": ("command", 1.0), "%": ("command", 0.01),
}
_ALIASES = {"µs": "us", "μs": "us", "sec": "s", "dps": "deg/s", "deg/sec": "deg/s", "rad/sec": "rad/s",
            "percent": "%", "pct": "%", "norm": "1", "normalised": "1", "normalized": "1", "[-1,1]": "1",
            "-1..1": "1"}
#: the units a time column may be in, s per unit
TIME_UNITS = {u: f for u, (q, f) in UNITS.items() if q == "time"}


def canonical(unit) -> str | None:
    """The canonical spelling of ``unit`` (None when it is not one rotorlab converts)."""
    if not isinstance(unit, str):
        return None
    u = unit.strip()
    u = _ALIASES.get(u.lower(), _ALIASES.get(u, u))
    return u if u in UNITS else None


def quantity(unit) -> str | None:
    """``"time"``, ``"angle"``, ``"angular rate"`` or ``"command"`` (None for a unit outside the table)."""
    c = canonical(unit)
    return UNITS[c][0] if c else None


def factor(from_unit, to_unit) -> float | None:
    """``k`` such that a value in ``from_unit`` times ``k`` is the value in ``to_unit``; None when the two are
    not the same quantity in the table (equal strings outside the table give 1)."""
    a, b = canonical(from_unit), canonical(to_unit)
    if a is None or b is None:
        return 1.0 if isinstance(from_unit, str) and from_unit.strip() == str(to_unit).strip() else None
    (qa, fa), (qb, fb) = UNITS[a], UNITS[b]
    return fa / fb if qa == qb else None
