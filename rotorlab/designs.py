"""Named controller designs flown in place of the cascade: the TUHH attitude designs of ref. 002 as
:class:`rotorlab.sim.control.statespace.ControllerSpec` on the twin's signals.

The designs come from ``rotorlab.tune`` (which never sees MuJoCo) and reach the simulator as matrices, so
``rotorlab.sim`` imports neither ``tune`` nor this module. Each design has one file's worth of code here and
one entry in :data:`DESIGNS`; ``tests/test_designs.py`` walks the registry.

Units. ``rotorlab.tune.loopshaping`` designs in SI units on the differential motor command ``b``
(``tau = K b``, each rotor of a pair gets ``+-b/2``): a controller from ``[r - angle (rad), -rate (rad/s)]`` to
``b``. The twin's flight software works in deg, deg/s and % with ``u = 100 b``, and reads the set-point,
the angle and the rate separately, so the controller's input matrix becomes ``[r, angle, rate] -> [r - angle,
-rate]`` times ``100 pi/180``. Every design is discretised with Tustin at the controller rate (the H-inf
design's own poles reach 87 rad/s; at 250 Hz Tustin's frequency warping there is under 2 %).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import control as ct
import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.lti import as_ss, c2d_zoh_delay
from rotorlab.sim.control.autopilot import parse_autopilot
from rotorlab.sim.control.statespace import AntiWindup, ControllerSpec, load_controller
from rotorlab.tune import riccati_antiwindup
from rotorlab.tune.loopshaping import TUHH_AXES, hinf_mixed_sensitivity, tuhh_axis_plant
from rotorlab.tune.loopshaping import modified_pid as mpid
from rotorlab.vehicles import load_vehicle

#: axis -> (set-point, angle, rate, command) signal names of the flight software
AXIS_SIGNALS = {"roll": ("phi_ref", "phi", "p", "u_lat"), "pitch": ("theta_ref", "theta", "q", "u_lon")}
DEG = math.pi / 180.0
#: the modified PID of ref. 002 fig. 4(b) on b per rad: tuned in tests/test_tune_loopshaping.py for the
#: published ~200 ms rise of a 10 deg step (0.18 s on the design model), the D part from the measured rate
MODIFIED_PID = {"kp": 0.45, "ki": 0.3, "kd": 0.08}


def _axis_plant(axis: str):
    return tuhh_axis_plant(axis, delay=False), TUHH_AXES[axis]["Td"]


def _to_twin(K, axis: str, dt: float, name: str, description: str, aw=None):
    """``K``: continuous 1x2 controller on ``[r - angle, -rate]`` (rad, rad/s) -> ``b``; ``aw``: discrete
    compensator at ``dt`` from :func:`rotorlab.tune.riccati_antiwindup` (input u~ in b; outputs u_d in b,
    y_d in rad and rad/s). Returns the ControllerSpec in deg, deg/s, %."""
    ref, ang, rate, cmd = AXIS_SIGNALS[axis]
    Kd = as_ss(ct.c2d(as_ss(K), dt, method="tustin"))
    M = np.array([[1.0, -1.0, 0.0], [0.0, 0.0, -1.0]]) * (100.0 * DEG)  # [r, angle, rate] deg -> e rad, times u = 100 b
    A, B, C, D = (np.asarray(X, float) for X in (Kd.A, Kd.B, Kd.C, Kd.D))
    awspec = None
    if aw is not None:
        Aa, Ba, Ca = (np.asarray(X, float) for X in (aw.A, aw.B, aw.C))
        # u~ in % -> b; u_d in b -> %; y_d in rad, rad/s -> deg, deg/s (what the controller's inputs read)
        awspec = AntiWindup(Aa, Ba / 100.0, np.diag([100.0, 1 / DEG, 1 / DEG]) @ Ca, (ang, rate))
    return ControllerSpec(name=name, dt_s=float(dt), inputs=(ref, ang, rate), outputs=(cmd,), A=A, B=B @ M, C=C,
                          D=D @ M, antiwindup=awspec, description=description)


def modified_pid(axis: str, dt: float):
    """Ref. 002's modified PID (fig. 4b): PI on the angle error plus D from the measured rate."""
    g = MODIFIED_PID
    return _to_twin(mpid(g["kp"], g["ki"], g["kd"]), axis, dt, f"modified-pid-{axis}",
                    f"ref. 002 modified PID on {axis}: kp {g['kp']}, ki {g['ki']} 1/s, kd {g['kd']} s (b per rad)")


def hinf_loopshaping(axis: str, dt: float):
    """Ref. 002 sec. 5 H-inf mixed-sensitivity (loop-shaping) design on the published axis model."""
    K, gamma = hinf_mixed_sensitivity(axis)
    return _to_twin(K, axis, dt, f"hinf-loopshaping-{axis}",
                    f"ref. 002 H-inf loop-shaping on {axis} (rotorlab.tune.hinf_mixed_sensitivity, gamma {gamma:.3f})")


def hinf_loopshaping_aw(axis: str, dt: float):
    """The H-inf design with ref. 002 sec. 6's Riccati anti-windup compensator, built on the design model
    sampled at the controller rate with its delay as whole samples (``rotorlab.tune.riccati_antiwindup``)."""
    K, gamma = hinf_mixed_sensitivity(axis)
    G, Td = _axis_plant(axis)
    theta = riccati_antiwindup(c2d_zoh_delay(G, dt, Td))
    return _to_twin(K, axis, dt, f"hinf-loopshaping-aw-{axis}",
                    f"ref. 002 H-inf loop-shaping on {axis} with the Riccati anti-windup compensator "
                    f"({theta.nstates} states)", aw=theta)


#: design name -> builder(axis, dt) -> ControllerSpec
DESIGNS = {"modified-pid": modified_pid, "hinf-loopshaping": hinf_loopshaping,
           "hinf-loopshaping-aw": hinf_loopshaping_aw}
#: vehicles whose twins the designs are made for (the published axis models)
DESIGN_VEHICLES = ("tuhh-quad",)


def list_designs() -> list[str]:
    return sorted(DESIGNS)


def design(name: str, vehicle="tuhh-quad", axes=("roll", "pitch"), dt_s: float | None = None) -> list:
    """The named design for ``vehicle``, one ControllerSpec per axis, at ``dt_s`` (default: the vehicle's
    flight-software period)."""
    if name not in DESIGNS:
        raise UnknownNameError("controller design", name, DESIGNS)
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    if v.name not in DESIGN_VEHICLES:
        raise ConfigError(f"design '{name}' is made for the published TUHH axis models", field="vehicle",
                          expected=f"one of {list(DESIGN_VEHICLES)}", got=v.name)
    for ax in axes:
        if ax not in AXIS_SIGNALS:
            raise UnknownNameError("axis", ax, AXIS_SIGNALS)
    dt = v.control_dt_s if dt_s is None else float(dt_s)
    return [_build(name, ax, dt) for ax in axes]


@functools.lru_cache(maxsize=32)
def _build(name: str, axis: str, dt: float):
    # an H-inf synthesis takes about a second; the specs are immutable, so one per (design, axis, rate)
    return DESIGNS[name](axis, dt)


def resolve_controller(value, vehicle):
    """``--controller`` value: a design name (both attitude axes), ``AUTOPILOT:PARAMS`` (an autopilot's own laws,
    :func:`rotorlab.sim.control.autopilot.parse_autopilot`) or a controller file path."""
    if value in DESIGNS:
        return design(value, vehicle)
    ap = parse_autopilot(value)
    if ap is not None:
        return ap
    p = Path(str(value))
    if p.suffix in (".json", ".toml"):
        return load_controller(p)
    raise UnknownNameError("controller (a design name, px4:PARAMS, ardupilot:PARAMS or a .json/.toml file)",
                           str(value), DESIGNS)


__all__ = ["DESIGNS", "MODIFIED_PID", "AXIS_SIGNALS", "list_designs", "design", "resolve_controller"]
