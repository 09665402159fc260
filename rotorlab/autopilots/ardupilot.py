"""ArduPilot (ArduCopter) attitude angle P and AC_PID rate loop, written from ArduPilot's source as formulas.

Sources (ArduPilot, ArduCopter 4.x):

* rate law: libraries/AC_PID/AC_PID.cpp (``update_all``, ``update_i``, ``get_ff``); the rate loop
  ``AC_AttitudeControl_Multi::rate_controller_run`` sends ``update_all(target, gyro) + get_ff()`` per axis to the
  motors as a normalised roll/pitch/yaw command; target and gyro in rad/s;
* filters: ``calc_lowpass_alpha_dt`` (libraries/AP_Math/AP_Math.cpp), see :mod:`rotorlab.autopilots.filters`;
  gyro: INS_GYRO_FILTER, a ``LowPassFilter2p`` (libraries/AP_InertialSensor);
* parameters: ``@Param`` blocks of libraries/AC_AttitudeControl/AC_AttitudeControl_Multi.cpp (rate PIDs) and
  AC_AttitudeControl.cpp (ANG_*_P, RATE_*_MAX); defaults from AC_AttitudeControl_Multi.h (AC_ATC_MULTI_RATE_*:
  roll/pitch FLTT = FLTD = 20 Hz, FLTE = 0; yaw FLTT = FLTD = 20 Hz, FLTE = 2.5 Hz) and AC_AttitudeControl.h
  (AC_ATTITUDE_CONTROL_ANGLE_P = 4.5).

The rate law per axis at the loop period ``dt`` (SCHED_LOOP_RATE), ``r`` the rate target, ``y`` the gyro
(INS_GYRO_FILTER applied), ``aT, aE, aD`` the alphas of FLTT, FLTE, FLTD:

    t[k] = t[k-1] + aT (r[k] - t[k-1])                 target filter
    e[k] = e[k-1] + aE ((t[k] - y[k]) - e[k-1])        error filter
    d[k] = d[k-1] + aD ((e[k] - e[k-1]) / dt - d[k-1]) derivative of the filtered error, filtered
    i[k] = clip(i[k-1] + I e[k] dt, -IMAX, IMAX)       (frozen while the motors report a limit and it would grow)
    u[k] = P e[k] + i[k] + D d[k] + FF t[k]

The integrator is updated before the output uses it (backward Euler), unlike PX4. The derivative acts on the
error, set-point included (softened by the target filter). The first call after a reset sets ``t = r``,
``e = r - y``, ``d = 0`` (AC_PID's ``_reset_filter``). Slew-rate limiting (SMAX) is off by default and not
modelled, nor are the notch filters.

The angle loop is ``rate_target = ANG_P * angle_error`` limited to RATE_*_MAX (0: no limit): the linear region
of ArduPilot's square-root controller, exact where ATC_ACCEL_*_MAX = 0 and for errors below
``accel_max / ANG_P^2`` (about 0.95 rad at the defaults); the angle error is taken per body axis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import control as ct
import numpy as np

from rotorlab.autopilots import filters
from rotorlab.autopilots.params import ParamSpec, ParamTable

__all__ = ["NAME", "FILE_FORMAT", "AXES", "LOOP_RATE_PARAM", "FILTER_GROUPS", "TABLE", "axis_names", "RateController",
           "AttitudeController", "rate_controller_lti", "attitude_controller_lti", "loop_hz"]

NAME = "ardupilot"
FILE_FORMAT = "parm"  # Mission Planner .parm
AXES = ("roll", "pitch", "yaw")
LOOP_RATE_PARAM = "SCHED_LOOP_RATE"  # the rate-loop rate, Hz
GYRO_FILTER_PARAM = "INS_GYRO_FILTER"  # the gyro low-pass the rate loop flies on (and RATE logs), Hz
#: the filter cutoffs a tuning may move (rotorlab tune --filters search), in groups moved together:
#: the gyro low-pass, and the rate PIDs' derivative filters moved together
FILTER_GROUPS = (("INS_GYRO_FILTER",), ("ATC_RAT_RLL_FLTD", "ATC_RAT_PIT_FLTD", "ATC_RAT_YAW_FLTD"))

_MULTI = "ArduCopter 4.x AC_AttitudeControl_Multi.cpp/.h"
_ATT = "ArduCopter 4.x AC_AttitudeControl.cpp/.h"
_INS = "ArduPilot AP_InertialSensor.cpp"
_SCHED = "ArduCopter 4.x AP_Scheduler.cpp"
_TAG = {"roll": "RLL", "pitch": "PIT", "yaw": "YAW"}
_AXIS_INDEX = (0, 1, 2)
_NO_FLAGS = (False, False, False)  # no motor limit reported
_RATE_MAX = {"roll": "ATC_RATE_R_MAX", "pitch": "ATC_RATE_P_MAX", "yaw": "ATC_RATE_Y_MAX"}


def axis_names(axis: str) -> dict[str, str]:
    """The parameter names of one axis by role: ``P, I, D, FF, IMAX, FLTT, FLTE, FLTD, ANG_P, RATE_MAX``."""
    t = _TAG[_axis(axis)]
    out = {k: f"ATC_RAT_{t}_{k}" for k in ("P", "I", "D", "FF", "IMAX", "FLTT", "FLTE", "FLTD")}
    out["ANG_P"] = f"ATC_ANG_{t}_P"
    out["RATE_MAX"] = _RATE_MAX[axis]
    return out


def _axis(axis: str) -> str:
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
    return axis


def _axis_specs(axis, p, i, d, d_max, p_rng, i_rng, flt):
    n = axis_names(axis)
    (t_rng, e_rng, dd_rng), (t_def, e_def, d_def) = flt
    return [
        ParamSpec(n["P"], "norm/(rad/s)", *p_rng, p, f"{axis} rate P gain: normalised output per rad/s of error",
                  _MULTI),
        ParamSpec(n["I"], "norm/rad", *i_rng, i, f"{axis} rate I gain: integrator growth per rad of integrated error",
                  _MULTI),
        ParamSpec(n["D"], "norm/(rad/s^2)", 0.0, d_max, d, f"{axis} rate D gain on the filtered error's derivative",
                  _MULTI),
        ParamSpec(n["FF"], "norm/(rad/s)", 0.0, 0.5, 0.0, f"{axis} rate feed-forward on the filtered target",
                  _MULTI),
        ParamSpec(n["IMAX"], "norm", 0.0, 1.0, 0.5, f"{axis} rate integrator limit (normalised output)", _MULTI),
        ParamSpec(n["FLTT"], "Hz", *t_rng, t_def, f"{axis} rate target filter cutoff (first order; 0: off)", _MULTI),
        ParamSpec(n["FLTE"], "Hz", *e_rng, e_def, f"{axis} rate error filter cutoff (first order; 0: off)", _MULTI),
        ParamSpec(n["FLTD"], "Hz", *dd_rng, d_def, f"{axis} rate derivative filter cutoff (first order; 0: off)",
                  _MULTI),
        ParamSpec(n["ANG_P"], "1/s", 3.0, 12.0, 4.5, f"{axis} angle P gain: rate target (rad/s) per rad of error",
                  _ATT),
        ParamSpec(n["RATE_MAX"], "deg/s", 0.0, 1080.0, 0.0, f"{axis} rate target limit (0: no limit)", _ATT),
    ]


_RP_FLT = (((5.0, 100.0), (0.0, 100.0), (5.0, 100.0)), (20.0, 0.0, 20.0))
TABLE = ParamTable(NAME, [
    *_axis_specs("roll", 0.135, 0.135, 0.0036, 0.05, (0.01, 0.5), (0.01, 2.0), _RP_FLT),
    *_axis_specs("pitch", 0.135, 0.135, 0.0036, 0.05, (0.01, 0.5), (0.01, 2.0), _RP_FLT),
    *_axis_specs("yaw", 0.18, 0.018, 0.0, 0.02, (0.10, 2.5), (0.01, 1.0),
                 (((1.0, 50.0), (0.0, 20.0), (5.0, 50.0)), (20.0, 2.5, 20.0))),
    ParamSpec("INS_GYRO_FILTER", "Hz", 0.0, 256.0, 20.0,
              "cutoff of the second-order low-pass on the gyro (0: off)", _INS),
    ParamSpec("SCHED_LOOP_RATE", "Hz", 50, 400, 400, "main loop rate, where the rate controller runs", _SCHED,
              integer=True),
])


def loop_hz(params: Mapping[str, float]) -> float:
    """The rate loop's rate, Hz (SCHED_LOOP_RATE, default 400)."""
    return float(params.get(LOOP_RATE_PARAM, TABLE[LOOP_RATE_PARAM].default))


def _gains(params, axis):
    n = axis_names(axis)
    return tuple(float(params[n[k]]) for k in ("P", "I", "D", "FF", "IMAX", "FLTT", "FLTE", "FLTD"))


def rate_controller_lti(params: Mapping[str, float], axis: str, dt_s: float,
                        gyro_filter: bool = True, fixed_structure: bool = False) -> ct.StateSpace:
    """ArduPilot's AC_PID rate law of one axis (plus feed-forward) as a discrete LTI system at ``dt_s``.

    Inputs ``["rate_sp", "rate"]`` (rad/s), output ``["torque"]`` (normalised roll/pitch/yaw command). ``rate`` is
    the raw gyro when ``gyro_filter`` (INS_GYRO_FILTER is part of the system), or the already filtered gyro
    (ArduPilot's logged RATE.R/P/Y) with ``gyro_filter=False``. Zero initial state is AC_PID after a reset fed
    zeros first; valid below IMAX and output saturation; equals :class:`RateController` there. With
    ``fixed_structure`` the I and D paths keep their states at zero gain: the matrices are then affine in
    ``(P, I, D, FF)`` for fixed filter cutoffs (the form a structured tuner varies).

    Examples
    --------
    >>> from rotorlab.autopilots import ardupilot
    >>> C = ardupilot.rate_controller_lti(ardupilot.TABLE.defaults(), "yaw", 1 / 400)
    >>> C.input_labels
    ['rate_sp', 'rate']
    """
    axis = _axis(axis)
    kp, ki, kd, ff, _, f_t, f_e, f_d = _gains(params, axis)
    one = ct.ss([], [], [], [[1.0]], dt_s)
    G = filters.butter2_ss(1.0 / dt_s, float(params["INS_GYRO_FILTER"])) if gyro_filter else one
    # [r, y] -> [t, yf]
    pre = ct.append(filters.alpha_ss(dt_s, f_t), G)
    # [t, yf] -> [t, e]: the error filter on t - yf, t passed through
    E = ct.series(ct.ss([], [], [], [[1.0, -1.0]], dt_s), filters.alpha_ss(dt_s, f_e))
    Ae, Be, Ce, De = (np.asarray(M, dtype=float) for M in (E.A, E.B, E.C, E.D))
    te = ct.ss(Ae, Be, np.vstack([np.zeros((1, Ae.shape[0])), Ce]), np.vstack([[1.0, 0.0], De]), dt_s)
    # [t, e] -> u
    sel_e = ct.ss([], [], [], [[0.0, 1.0]], dt_s)
    core = ct.ss([], [], [], [[ff, kp]], dt_s)
    if ki or fixed_structure:
        # i[k] = i[k-1] + ki dt e[k]: ki dt z / (z - 1)
        core = ct.parallel(core, ct.series(sel_e, ct.ss([[1.0]], [[ki * dt_s]], [[1.0]], [[ki * dt_s]], dt_s)))
    if kd or fixed_structure:
        # d = Dlpf((e[k] - e[k-1]) / dt); state e[k-1]
        diff = ct.ss([[0.0]], [[1.0]], [[-1.0 / dt_s]], [[1.0 / dt_s]], dt_s)
        core = ct.parallel(core, ct.series(sel_e, diff, filters.alpha_ss(dt_s, f_d), ct.ss([], [], [], [[kd]], dt_s)))
    C = ct.series(pre, te, core)
    return ct.ss(C.A, C.B, C.C, C.D, dt_s, inputs=["rate_sp", "rate"], outputs=["torque"],
                 name=f"ardupilot_rate_{axis}")


def attitude_controller_lti(params: Mapping[str, float], axis: str, dt_s: float) -> ct.StateSpace:
    """ArduPilot's angle P of one axis: ``rate_target = ANG_P (angle_sp - angle)``, inputs ``["angle_sp", "angle"]``
    (rad), output ``["rate_sp"]`` (rad/s), below the rate limit and in the square-root controller's linear region.

    Examples
    --------
    >>> from rotorlab.autopilots import ardupilot
    >>> float(ardupilot.attitude_controller_lti(ardupilot.TABLE.defaults(), "roll", 0.0025).D[0, 1])
    -4.5
    """
    p = float(params[axis_names(axis)["ANG_P"]])
    return ct.ss([], [], [], [[p, -p]], dt_s, inputs=["angle_sp", "angle"], outputs=["rate_sp"],
                 name=f"ardupilot_att_{axis}")


class RateController:
    """ArduPilot's three AC_PID rate controllers (plus feed-forward), one call per loop tick, in plain floats.

    Parameters
    ----------
    params : mapping
        ArduPilot parameters by name (complete for the rate law).
    dt_s : float
        Loop period, s.
    gyro_filter : bool
        Run INS_GYRO_FILTER on the ``rate`` given to :meth:`step` (False when it is already filtered).

    Attributes
    ----------
    integral : list of float
        The integrators (normalised output; ArduPilot's PID log ``I``).

    Examples
    --------
    >>> from rotorlab.autopilots import ardupilot
    >>> rc = ardupilot.RateController(ardupilot.TABLE.defaults(), 1 / 400)
    >>> _ = rc.step([0.0] * 3, [0.0] * 3)
    >>> rc.step([1.0, 0.0, 0.0], [0.0] * 3)[0] > 0
    True
    """

    def __init__(self, params: Mapping[str, float], dt_s: float, gyro_filter: bool = True):
        self.dt = float(dt_s)
        self._axes = []
        for a in AXES:
            kp, ki, kd, ff, imax, f_t, f_e, f_d = _gains(params, a)
            self._axes.append((kp, ki, kd, ff, imax, filters.alpha_lowpass(self.dt, f_t),
                               filters.alpha_lowpass(self.dt, f_e), filters.alpha_lowpass(self.dt, f_d)))
        b, a_ = filters.butter2_coeffs(1.0 / self.dt, float(params["INS_GYRO_FILTER"]) if gyro_filter else 0.0)
        self._gyro = (*(float(v) for v in b), float(a_[1]), float(a_[2]))
        self.reset()

    def reset(self) -> None:
        """Zero the integrators and filters; the next call re-initialises the filters from its inputs."""
        self._g = [[0.0, 0.0] for _ in AXES]
        self.target = [0.0, 0.0, 0.0]
        self.error = [0.0, 0.0, 0.0]
        self.derivative = [0.0, 0.0, 0.0]
        self.integral = [0.0, 0.0, 0.0]
        self._reset_filter = True

    def step(self, rate_sp, rate, limit=None) -> tuple:
        """One tick: normalised ``(roll, pitch, yaw)`` command from the rate target and the gyro (rad/s).

        ``limit`` (bool per axis): the motors report saturation on that axis, so the integrator may only shrink.
        """
        # it runs every tick: each axis's gains and states come out of one zip, not indexed per use
        gb0, gb1, gb2, ga1, ga2 = self._gyro
        dt = self.dt
        first = self._reset_filter
        self._reset_filter = False
        target, error, derivative, integral = self.target, self.error, self.derivative, self.integral
        out = []
        for i, r, gyro, (kp, ki, kd, ff, imax, a_t, a_e, a_d), g, lim in zip(
                _AXIS_INDEX, rate_sp, rate, self._axes, self._g, _NO_FLAGS if limit is None else limit):
            g0, g1 = g
            x0 = gyro - ga1 * g0 - ga2 * g1
            y = gb0 * x0 + gb1 * g0 + gb2 * g1
            g[0], g[1] = x0, g0
            if first:
                t, e, d = r, r - y, 0.0
            else:
                t = target[i]
                t += a_t * (r - t)
                e_last = error[i]
                e = e_last + a_e * ((t - y) - e_last)
                d = derivative[i]
                d += a_d * ((e - e_last) / dt - d)
            target[i], error[i], derivative[i] = t, e, d
            integ = integral[i]
            if ki == 0.0:
                integ = 0.0
            elif not lim or (integ > 0.0 and e < 0.0) or (integ < 0.0 and e > 0.0):
                integ += e * ki * dt
                integ = imax if integ > imax else (-imax if integ < -imax else integ)
            integral[i] = integ
            out.append(kp * e + integ + kd * d + ff * t)
        return tuple(out)


class AttitudeController:
    """ArduPilot's angle P: body rate target from the per-axis attitude error, limited to ATC_RATE_*_MAX.

    The error is the rotation vector of ``q^-1 q_sp`` (quaternions ``(w, x, y, z)``, body to world).

    Examples
    --------
    >>> import math
    >>> from rotorlab.autopilots import ardupilot
    >>> att = ardupilot.AttitudeController(ardupilot.TABLE.defaults())
    >>> [round(v, 4) for v in att.update((1, 0, 0, 0), (math.cos(0.05), math.sin(0.05), 0, 0))]
    [0.45, 0.0, 0.0]
    """

    def __init__(self, params: Mapping[str, float]):
        self.p = tuple(float(params[axis_names(a)["ANG_P"]]) for a in AXES)
        lim = (math.radians(float(params[_RATE_MAX[a]])) for a in AXES)
        self.rate_limit = tuple(v if v > 0 else math.inf for v in lim)

    def update(self, q, q_sp) -> tuple:
        """Body rate target ``(p, q, r)``, rad/s, from the attitude ``q`` and its set-point ``q_sp``."""
        # written out in floats, the axes unrolled: it runs every tick
        w1, x1, y1, z1 = float(q[0]), -float(q[1]), -float(q[2]), -float(q[3])  # q^-1 of a unit quaternion
        w2, x2, y2, z2 = map(float, q_sp)
        w = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
        v0, v1, v2 = (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                      w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)
        if w < 0.0:
            w, v0, v1, v2 = -w, -v0, -v1, -v2
        s = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        k = 0.0 if s < 1e-12 else 2.0 * math.atan2(s, w) / s
        p0, p1, p2 = self.p
        l0, l1, l2 = self.rate_limit
        r0, r1, r2 = p0 * v0 * k, p1 * v1 * k, p2 * v2 * k
        return (l0 if r0 > l0 else (-l0 if r0 < -l0 else r0), l1 if r1 > l1 else (-l1 if r1 < -l1 else r1),
                l2 if r2 > l2 else (-l2 if r2 < -l2 else r2))
