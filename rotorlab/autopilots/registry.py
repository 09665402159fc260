"""The registry of autopilots: name -> module with the common interface (see :mod:`rotorlab.autopilots`)."""

from __future__ import annotations

from rotorlab.autopilots import ardupilot, px4
from rotorlab.errors import UnknownNameError

__all__ = ["AUTOPILOTS", "get"]

AUTOPILOTS = {px4.NAME: px4, ardupilot.NAME: ardupilot}


def get(name: str):
    """The autopilot module registered under ``name`` (``"px4"``, ``"ardupilot"``).

    Raises
    ------
    rotorlab.errors.UnknownNameError
        Listing the registered names.

    Examples
    --------
    >>> get("px4").FILE_FORMAT
    'qgc'
    """
    try:
        return AUTOPILOTS[name]
    except KeyError:
        raise UnknownNameError("autopilot", name, AUTOPILOTS) from None
