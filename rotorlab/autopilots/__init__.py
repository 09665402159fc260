"""The autopilots' own controller laws, written once, for the flight software, identification and tuning.

Each autopilot is one module with the same interface, registered in :data:`AUTOPILOTS`:

* ``TABLE``: its :class:`~rotorlab.autopilots.params.ParamTable` (names, units, documented ranges, defaults,
  sources), ``AXES``, ``axis_names(axis)`` (parameter names by role), ``loop_hz(params)``;
* ``rate_controller_lti(params, axis, dt_s, gyro_filter=True)``: the rate law of one axis as a discrete
  ``control.StateSpace``, inputs ``["rate_sp", "rate"]`` in rad/s, output ``["torque"]`` normalised;
* ``attitude_controller_lti(params, axis, dt_s)``: the angle law linearised, inputs ``["angle_sp", "angle"]``
  (rad), output ``["rate_sp"]`` (rad/s);
* ``RateController(params, dt_s)`` and ``AttitudeController(params)``: the stateful laws the flight software
  steps once per tick;
* ``FILE_FORMAT``: the ground station's parameter file it reads and writes (``"qgc"`` .params, ``"parm"``).

:func:`closed_loop_lti` closes an autopilot's attitude and rate loops (or the rate loop alone) around a plant model
at the loop rate: the linear analysis of what the flight software flies.

This package is on the ground floor: it imports neither MuJoCo nor ``rotorlab.sim``, ``.ident`` or ``.tune``.

Examples
--------
>>> from rotorlab import autopilots
>>> ap = autopilots.get("px4")
>>> C = ap.rate_controller_lti(ap.TABLE.defaults(), "pitch", 1 / 400)
>>> C.dt
0.0025
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rotorlab.autopilots import ardupilot, px4
from rotorlab.autopilots.loops import closed_loop_lti
from rotorlab.autopilots.params import read_mp_parm, read_params, read_qgc_params, write_mp_parm, write_qgc_params
from rotorlab.autopilots.registry import AUTOPILOTS, get

__all__ = ["AUTOPILOTS", "get", "read_params", "read_qgc_params", "read_mp_parm", "write_params",
           "closed_loop_lti", "ardupilot", "px4"]

def write_params(autopilot: str, path, params: Mapping[str, float], header: str) -> Path:
    """Write a tuned parameter set in the autopilot's own file format (QGroundControl .params for PX4, Mission
    Planner .parm for ArduPilot), only the parameters given, after checking every name and range against the
    autopilot's table; ``header`` says what was tuned against which goals.

    Raises
    ------
    rotorlab.errors.ConfigError
        An unknown name or a value outside its documented range (the message gives the range and its source).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from rotorlab import autopilots
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "tuned.params"
    >>> _ = autopilots.write_params("px4", p, {"MC_ROLLRATE_P": 0.18}, "roll rate P")
    >>> autopilots.read_params(p)
    {'MC_ROLLRATE_P': 0.18}
    """
    ap = get(autopilot)
    if ap.FILE_FORMAT == "qgc":
        return write_qgc_params(path, params, ap.TABLE, header)
    return write_mp_parm(path, params, ap.TABLE, header)
