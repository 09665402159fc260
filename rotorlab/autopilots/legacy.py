"""Parameters of older autopilot versions mapped onto the names the current laws read, in one table.

A log keeps the parameters of the firmware that flew it. The laws in :mod:`rotorlab.autopilots` read today's
names; older firmware had other names, or no parameter at all because the law had no such term (then the value
that reproduces that law is used). Each rule of :data:`RULES` says which current parameter it fills, from which
legacy parameter (or none), the version boundary, the rule and its source. A rule applies only when the current
name is absent; a value the log has always wins.

ArduCopter before 4.0 (AC_PID with one ``FILT``; source read: AC_PID.cpp ``set_input_filter_d`` /
``set_input_filter_all`` and AC_AttitudeControl.cpp ``rate_target_to_motor_roll/pitch/yaw`` of ArduCopter 3.4):

* roll and pitch call ``set_input_filter_d(rate_error)``: P and I act on the unfiltered error, the derivative of
  the error is low-passed at ``FILT`` (``_derivative += alpha (de/dt - _derivative)``): ``FLTD = FILT``,
  ``FLTE = 0``;
* yaw calls ``set_input_filter_all(rate_error)``: the error itself is low-passed at ``FILT`` and P, I and the
  unfiltered difference of the filtered error use it: ``FLTE = FILT``, ``FLTD = 0``;
* there was no target filter (``FLTT = 0``); the 3.4 output sums ``get_p() + integrator + get_d()``: no
  feed-forward term (``FF = 0``); no rate-target limit parameter (``ATC_RATE_*_MAX = 0``, no limit).

PX4 before the ``IMU_*`` gyro parameters and ``MC_*RATE_K`` (mc_att_control_main.cpp of 2016-2017,
``control_attitude_rates``):

* ``att_control = P e + int + D (rates_prev - rates) / dt + FF rates_sp``: no K (``MC_*RATE_K = 1``), the
  derivative of the rate differenced without a D-term filter (``IMU_DGYRO_CUTOFF = 0``) unless the log has
  ``MC_DTERM_CUTOFF`` (2017-2019, a low-pass on the rate before differencing; LTI filter and difference commute,
  so it is the D-term cutoff);
* the integrator limit was the constant ``RATES_I_LIMIT = 0.3`` before ``MC_*R_INT_LIM``;
* no yaw torque low-pass (``MC_YAW_TQ_CUTOFF = 0``);
* the gyro was filtered in its driver (``IMU_GYRO_CUTOFF`` unused when the logged rate is the filtered one);
* the controller ran once per attitude (gyro) update: 250 Hz on Pixhawk-class boards (``IMU_GYRO_RATEMAX = 250``).

Throttle PID attenuation (``MC_TPA_*``, 2016-2019), a gain schedule on thrust, is not part of the LTI law: a log
that has it active gets a note (:func:`upgrade` returns it among the mappings with ``rule = "not modelled"``).

Examples
--------
>>> params, mapped = upgrade("ardupilot", {"ATC_RAT_RLL_FILT": 20.0})
>>> params["ATC_RAT_RLL_FLTD"], params["ATC_RAT_RLL_FLTE"]
(20.0, 0.0)
>>> mapped[0].name, mapped[0].legacy
('ATC_RAT_RLL_FLTT', 'ATC_RAT_RLL_FILT')
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Rule", "Mapped", "RULES", "upgrade"]

_AP34 = "ArduCopter 3.4 AC_PID.cpp set_input_filter_d/_all, AC_AttitudeControl.cpp rate_target_to_motor_*"
_PX4_OLD = "PX4 mc_att_control_main.cpp control_attitude_rates (2016-2017)"


@dataclass(frozen=True)
class Rule:
    """How one current parameter is filled for a log of older firmware.

    Attributes
    ----------
    autopilot : str
    name : str
        The current name the law reads.
    legacy : str or None
        The older parameter it comes from; ``None``: the older law had no such parameter. A rule with a legacy
        name applies only when that name is in the log.
    value : float or None
        The value used when ``legacy`` is ``None`` or ``copy`` is False.
    copy : bool
        Take the legacy parameter's value (else ``value``).
    boundary : str
        Which versions lack ``name``.
    why : str
        The older law's term this reproduces.
    source : str
    """

    autopilot: str
    name: str
    legacy: str | None
    value: float | None
    copy: bool
    boundary: str
    why: str
    source: str


@dataclass(frozen=True)
class Mapped:
    """One parameter filled by a rule: ``name = value`` (from ``legacy`` when not None), the rule and why."""

    name: str
    value: float
    legacy: str | None
    rule: str
    why: str
    source: str

    def text(self) -> str:
        frm = f" from {self.legacy}" if self.legacy else ""
        return f"{self.name} = {self.value:g}{frm} ({self.rule}: {self.why}; {self.source})"


def _ardupilot_rules():
    out = []
    for axis, tag in (("roll", "RLL"), ("pitch", "PIT"), ("yaw", "YAW")):
        filt = f"ATC_RAT_{tag}_FILT"
        b = "ArduCopter < 4.0 (one FILT per rate PID)"
        out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FLTT", filt, 0.0, False, b, "no target filter", _AP34))
        if axis == "yaw":
            out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FLTE", filt, None, True, b,
                            "yaw: set_input_filter_all low-passes the error at FILT", _AP34))
            out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FLTD", filt, 0.0, False, b,
                            "yaw: the derivative is the unfiltered difference of the filtered error", _AP34))
        else:
            out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FLTE", filt, 0.0, False, b,
                            f"{axis}: set_input_filter_d: P and I on the unfiltered error", _AP34))
            out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FLTD", filt, None, True, b,
                            f"{axis}: set_input_filter_d low-passes the error's derivative at FILT", _AP34))
        out.append(Rule("ardupilot", f"ATC_RAT_{tag}_FF", filt, 0.0, False, b,
                        "the output is P + I + D, no feed-forward", _AP34))
        rmax = {"roll": "ATC_RATE_R_MAX", "pitch": "ATC_RATE_P_MAX", "yaw": "ATC_RATE_Y_MAX"}[axis]
        out.append(Rule("ardupilot", rmax, filt, 0.0, False, b, "no rate-target limit parameter (0: no limit)",
                        _AP34))
    return out


def _px4_rules():
    out = []
    b_k = "PX4 before MC_*RATE_K (2019)"
    for axis, short in (("ROLL", "RR"), ("PITCH", "PR"), ("YAW", "YR")):
        out.append(Rule("px4", f"MC_{axis}RATE_K", None, 1.0, False, b_k, "the law had no K (parallel P, I, D)",
                        _PX4_OLD))
        out.append(Rule("px4", f"MC_{short}_INT_LIM", None, 0.3, False, "PX4 before MC_*_INT_LIM (2016)",
                        "the integrator limit was the constant RATES_I_LIMIT = 0.3", _PX4_OLD))
    b_imu = "PX4 before the IMU_* gyro parameters (2018-2020)"
    out += [
        Rule("px4", "IMU_DGYRO_CUTOFF", "MC_DTERM_CUTOFF", None, True, b_imu,
             "MC_DTERM_CUTOFF low-passed the rate before differencing: the same LTI D-term filter",
             "PX4 mc_att_control_main.cpp (2017-2019, _lp_filters_d)"),
        Rule("px4", "IMU_DGYRO_CUTOFF", None, 0.0, False, b_imu,
             "D (rates_prev - rates) / dt: the derivative without a filter", _PX4_OLD),
        Rule("px4", "IMU_GYRO_CUTOFF", None, 0.0, False, b_imu,
             "the gyro was filtered in its driver; the logged rate is the filtered one", _PX4_OLD),
        Rule("px4", "IMU_GYRO_RATEMAX", None, 250.0, False, b_imu,
             "the controller ran once per attitude update, 250 Hz on Pixhawk-class boards", _PX4_OLD),
        Rule("px4", "MC_YAW_TQ_CUTOFF", None, 0.0, False, "PX4 before MC_YAW_TQ_CUTOFF (absent up to v1.15-dev)",
             "no low-pass on the yaw torque", _PX4_OLD),
    ]
    return out


RULES: tuple[Rule, ...] = tuple(_ardupilot_rules() + _px4_rules())

# PX4's throttle PID attenuation (2016-2019): active when a rate below 1 is set for a breakpoint below 1
_TPA = (("MC_TPA_RATE_P", "MC_TPA_BREAK_P"), ("MC_TPA_RATE_D", "MC_TPA_BREAK_D"), ("MC_TPA_SLOPE", "MC_TPA_BREAK"))


def upgrade(autopilot: str, params: Mapping[str, float]) -> tuple[dict[str, float], list[Mapped]]:
    """``params`` with every current name a rule of :data:`RULES` can fill added, and what was filled.

    Names already present are never changed. Rules are tried in table order; the first that applies to a name
    fills it (a legacy parameter before the value the older law had without one). A PX4 throttle PID attenuation
    that is active is returned as a :class:`Mapped` with ``rule = "not modelled"`` (nothing is filled).

    Parameters
    ----------
    autopilot : {"px4", "ardupilot"}
    params : mapping
        The log's parameters by name.

    Returns
    -------
    params : dict
        A copy with the filled names.
    mapped : list of Mapped
        One per filled name (and per unmodelled feature), to report.

    Examples
    --------
    >>> p, m = upgrade("px4", {"MC_ROLLRATE_P": 0.19})
    >>> p["MC_ROLLRATE_K"], p["IMU_DGYRO_CUTOFF"]
    (1.0, 0.0)
    >>> upgrade("px4", {"MC_ROLLRATE_K": 2.0})[0]["MC_ROLLRATE_K"]
    2.0
    """
    out = dict(params)
    mapped: list[Mapped] = []
    for r in RULES:
        if r.autopilot != autopilot or r.name in out:
            continue
        if r.legacy is not None and r.legacy not in params:
            continue
        value = float(params[r.legacy]) if r.copy else float(r.value)
        out[r.name] = value
        mapped.append(Mapped(r.name, value, r.legacy, "renamed" if r.copy else "older law", r.why,
                             f"{r.boundary}; {r.source}"))
    if autopilot == "px4":
        for rate, brk in _TPA:
            if rate in params and brk in params and float(params[brk]) < 1.0 and (
                    float(params[rate]) > 0.0 if rate != "MC_TPA_SLOPE" else float(params[rate]) != 0.0):
                mapped.append(Mapped(rate, float(params[rate]), brk, "not modelled",
                                     f"throttle PID attenuation above {brk} = {float(params[brk]):g} scales the "
                                     "gains with thrust; the LTI law uses the unattenuated gains", _PX4_OLD))
    return out, mapped
