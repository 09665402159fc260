"""An autopilot's own attitude and rate laws flown in the twin (``--controller px4:PARAMS``,
``--controller ardupilot:PARAMS``), from :mod:`rotorlab.autopilots` (the laws are written once there).

Each tick the plug-in reads the flight software's attitude and set-points (``phi, theta, psi`` and
``phi_ref, theta_ref, psi_ref``, deg) and the gyro (``p, q, r``, deg/s), runs the autopilot's attitude law (rate
set-point, rad/s) and rate law (normalised torque) at the flight-software rate, and sets the commands
``u_lat, u_lon, u_yaw = 100 % x torque``: a normalised torque of 1 is a differential command of 100 %, opposite
rotors +-50 % (rotorlab's convention, the one its designs use: ``u = 100 b``, ``b`` the differential motor
command; PX4's allocator normalisation and ArduPilot's motor mixer scaling are not modelled). The flight software
then saturates the commands and mixes them. The commands clipped at the previous tick are the allocator's
saturation flags (PX4) or the motors' limit flags (ArduPilot) for the integrators.

With ``rate_reference`` (a callable ``t -> (p, q, r)`` set-point in deg/s) the attitude law is bypassed: the
autopilot's rate (acro) mode. With ``rate_excitation`` (a callable ``t -> (p, q, r)`` in deg/s) the attitude law
flies and the excitation is added to its rate set-point, where PX4's autotune (``autotune_attitude_control_status
.rate_sp``, added by mc_att_control) and ArduCopter's SYSID mode on its rate axes (``rate_bf_*_sysid``) inject theirs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from pathlib import Path

from rotorlab import autopilots
from rotorlab.errors import ConfigError

__all__ = ["AutopilotSpec", "AutopilotController", "parse_autopilot", "euler_to_quat", "TORQUE_TO_PCT"]

TORQUE_TO_PCT = 100.0
_D2R = math.pi / 180.0


def euler_to_quat(phi_rad: float, theta_rad: float, psi_rad: float) -> tuple:
    """Quaternion ``(w, x, y, z)`` of the yaw-pitch-roll (Z-Y-X) Euler angles, body (FRD) to world (NED)."""
    # x * 0.5 is x / 2 exactly, and float * float is the cheaper operation in CPython (as 2.0 for 2 in the laws)
    h, t, y = phi_rad * 0.5, theta_rad * 0.5, psi_rad * 0.5
    cr, sr = math.cos(h), math.sin(h)
    cp, sp = math.cos(t), math.sin(t)
    cy, sy = math.cos(y), math.sin(y)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy)


@dataclasses.dataclass(frozen=True)
class AutopilotSpec:
    """An autopilot law to fly: ``autopilot`` (a name in :data:`rotorlab.autopilots.AUTOPILOTS`), its complete
    parameter set in the autopilot's names and units, and where the parameters came from.

    Examples
    --------
    >>> spec = AutopilotSpec.from_params("ardupilot", {"ATC_RAT_PIT_P": 0.1}, source="tuned.parm")
    >>> spec.name, spec.params["ATC_RAT_PIT_P"], "ATC_RAT_PIT_P" in spec.defaulted
    ('ardupilot:tuned.parm', 0.1, False)
    """

    autopilot: str
    params: Mapping[str, float]
    source: str = "defaults"
    defaulted: tuple = ()

    #: the flight-software signals the laws read and the commands they set
    inputs = ("phi", "theta", "psi", "phi_ref", "theta_ref", "psi_ref", "p", "q", "r")
    outputs = ("u_lat", "u_lon", "u_yaw")

    @property
    def name(self) -> str:
        return f"{self.autopilot}:{self.source}"

    @classmethod
    def from_params(cls, autopilot: str, params: Mapping[str, float] | None = None, source: str = "defaults"):
        """The autopilot's table filled from ``params`` (None: every default); the names left at their default are
        kept in ``defaulted``."""
        ap = autopilots.get(autopilot)
        given = dict(params or {})
        full = ap.TABLE.complete(given, fill_defaults=True)
        return cls(autopilot, full, source, tuple(n for n in full if n not in given))


def parse_autopilot(value: str) -> AutopilotSpec | None:
    """``--controller`` value ``AUTOPILOT:PARAMS`` -> :class:`AutopilotSpec`, or None when ``value`` names no
    registered autopilot before a colon. ``PARAMS``: ``defaults``, or a parameter file (QGroundControl
    ``.params``, Mission Planner ``.parm``, ArduPilot ``.param``); parameters the file does not set keep the
    autopilot's defaults (a tuned set lists only what was tuned).

    Raises
    ------
    rotorlab.errors.ConfigError
        A missing or unreadable file, a bad row (the file, line and field named).

    Examples
    --------
    >>> parse_autopilot("px4:defaults").params["MC_ROLLRATE_P"]
    0.15
    """
    head, sep, rest = str(value).partition(":")
    if not sep or head not in autopilots.AUTOPILOTS:
        return None
    if rest == "defaults":
        return AutopilotSpec.from_params(head)
    path = Path(rest)
    if not path.is_file():
        raise ConfigError("parameter file not found", file=path, field="controller",
                          expected=f"'{head}:defaults' or '{head}:' and a .params/.parm/.param file", got=value)
    return AutopilotSpec.from_params(head, autopilots.read_params(path), source=str(path))


class AutopilotController:
    """The plug-in flying an :class:`AutopilotSpec` (module docstring).

    Parameters
    ----------
    spec : AutopilotSpec
    dt_s : float
        Flight-software period, s: the autopilot's loop period in the twin.
    u_limit_pct, yaw_u_limit_pct : float
        The flight software's command saturations, for the integrators' saturation flags.
    rate_reference : callable, optional
        ``t -> (p, q, r)`` rate set-point, deg/s: rate mode, no attitude law.
    rate_excitation : callable, optional
        ``t -> (p, q, r)``, deg/s, added to the attitude law's rate set-point (the autopilots' identification
        excitation); the rate set-points returned include it.

    Examples
    --------
    >>> ctl = AutopilotController(AutopilotSpec.from_params("px4"), 1 / 250)
    >>> sig = dict(phi=0.0, theta=0.0, psi=0.0, phi_ref=1.0, theta_ref=0.0, psi_ref=0.0, p=0.0, q=0.0, r=0.0)
    >>> round(ctl.step(0.0, sig)["p_ref"], 3)  # 1 deg of roll error at MC_ROLL_P = 4: 4 deg/s
    4.0

    Attributes
    ----------
    add_commands : bool
        Add the commands the flight software holds at the plug-in's turn to the autopilot's output. The runner
        sets it together with :attr:`FlightSoftware.attitude_by_plugin
        <rotorlab.sim.control.flight_software.FlightSoftware.attitude_by_plugin>`: with the cascade off those
        commands are the command excitation alone, which then reaches the mixer as PX4's torque injection does.
    flies_rate_loop : bool
        True: the rate set-points it returns (``p_ref``, ``q_ref``, ``r_ref``) are the ones its rate loop flew,
        so the flight software logs them in place of its own (any other plug-in returning a flight-software
        signal is refused).
    """

    flies_rate_loop = True

    def __init__(self, spec: AutopilotSpec, dt_s: float, u_limit_pct: float = math.inf,
                 yaw_u_limit_pct: float = math.inf, rate_reference: Callable | None = None,
                 rate_excitation: Callable | None = None):
        if not isinstance(spec, AutopilotSpec):
            raise ConfigError(field="controller", expected="an AutopilotSpec", got=type(spec).__name__)
        self.spec = spec
        self.dt = float(dt_s)
        self.ap = autopilots.get(spec.autopilot)
        self.rate = self.ap.RateController(spec.params, self.dt)
        self.att = self.ap.AttitudeController(spec.params)
        self._rate_step, self._att_update = self.rate.step, self.att.update
        self.limits = (float(u_limit_pct), float(u_limit_pct), float(yaw_u_limit_pct))
        self._px4 = spec.autopilot == "px4"
        self.rate_reference = rate_reference
        self.rate_excitation = rate_excitation
        self.outputs = spec.outputs
        self.add_commands = False
        self.reset()

    def reset(self) -> None:
        self.rate.reset()
        self._sat_pos = (False, False, False)
        self._sat_neg = (False, False, False)

    def step(self, t: float, sig: dict) -> dict:
        """One tick from the flight software's signals (the plug-in protocol): the commands and the rate
        set-points (deg/s) by name (:meth:`fly`)."""
        if self.add_commands:
            u_lat, u_lon, u_yaw = sig["u_lat"], sig["u_lon"], sig["u_yaw"]
        else:
            u_lat = u_lon = u_yaw = 0.0
        out = self.fly(t, sig["phi"], sig["theta"], sig["psi"], sig["phi_ref"], sig["theta_ref"], sig["psi_ref"],
                       sig["p"], sig["q"], sig["r"], u_lat, u_lon, u_yaw)
        return dict(zip(("u_lat", "u_lon", "u_yaw", "p_ref", "q_ref", "r_ref"), out))

    def fly(self, t: float, phi, theta, psi, phi_ref, theta_ref, psi_ref, p, q, r, u_lat=0.0, u_lon=0.0,
            u_yaw=0.0) -> tuple:
        """One tick from floats: attitude and its set-point (deg), gyro (deg/s) and, with :attr:`add_commands`,
        the commands to add (%). Returns ``(u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref)`` (%, deg/s).
        :class:`~rotorlab.sim.control.flight_software.FlightSoftware` calls it directly when the autopilot is its
        only plug-in, so a tick gathers and builds no dict for it.

        Examples
        --------
        >>> ctl = AutopilotController(AutopilotSpec.from_params("px4"), 1 / 250)
        >>> u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref = ctl.fly(0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        >>> round(p_ref, 3), round(u_lat, 3)  # MC_ROLL_P = 4: 4 deg/s; MC_ROLLRATE_P = 0.15 per rad/s: 1.047 %
        (4.0, 1.047)
        """
        # plain floats throughout, the laws' methods bound once (__init__): it runs every tick
        if self.rate_reference is not None:
            # unpacked, not a generator: Cython compiles no closure inside a cpdef method (autopilot.pxd)
            p_sp, q_sp, r_sp = self.rate_reference(t)
            rate_sp = (float(p_sp) * _D2R, float(q_sp) * _D2R, float(r_sp) * _D2R)
        else:
            rate_sp = self._att_update(euler_to_quat(phi * _D2R, theta * _D2R, psi * _D2R),
                                       euler_to_quat(phi_ref * _D2R, theta_ref * _D2R, psi_ref * _D2R))
            if self.rate_excitation is not None:
                ex = self.rate_excitation(t)
                rate_sp = (rate_sp[0] + ex[0] * _D2R, rate_sp[1] + ex[1] * _D2R, rate_sp[2] + ex[2] * _D2R)
        gyro = (p * _D2R, q * _D2R, r * _D2R)
        sat_pos, sat_neg = self._sat_pos, self._sat_neg
        if self._px4:
            tq0, tq1, tq2 = self._rate_step(rate_sp, gyro, sat_pos, sat_neg)
        else:
            tq0, tq1, tq2 = self._rate_step(rate_sp, gyro, (sat_pos[0] or sat_neg[0], sat_pos[1] or sat_neg[1],
                                                            sat_pos[2] or sat_neg[2]))
        u0, u1, u2 = TORQUE_TO_PCT * tq0, TORQUE_TO_PCT * tq1, TORQUE_TO_PCT * tq2
        if self.add_commands:
            u0, u1, u2 = u0 + u_lat, u1 + u_lon, u2 + u_yaw
        l0, l1, l2 = self.limits
        self._sat_pos = (u0 > l0, u1 > l1, u2 > l2)
        self._sat_neg = (u0 < -l0, u1 < -l1, u2 < -l2)
        r0, r1, r2 = rate_sp
        return u0, u1, u2, r0 / _D2R, r1 / _D2R, r2 / _D2R
