"""PX4 multicopter attitude and rate control, written from PX4's source and parameter metadata as formulas.

Sources (PX4-Autopilot, main branch; commits named where the stored copy was read):

* rate law: src/lib/rate_control/rate_control.cpp (``RateControl::update``, ``updateIntegral``, 0155b3a8);
  K scaling: src/modules/mc_rate_control/MulticopterRateControl.cpp (``parameters_updated``); yaw torque
  low-pass: the same file (``_output_lpf_yaw.update(torque(2), dt)``, an AlphaFilter at MC_YAW_TQ_CUTOFF);
* gyro and D-term filters: src/modules/sensors/vehicle_angular_velocity/VehicleAngularVelocity.cpp (4201200a):
  the gyro is low-passed at IMU_GYRO_CUTOFF, differentiated, and the derivative low-passed at IMU_DGYRO_CUTOFF;
  both are ``math::LowPassFilter2p`` (see :mod:`rotorlab.autopilots.filters`);
* attitude law: src/modules/mc_att_control/AttitudeControl/AttitudeControl.cpp (``update``, 305966ee);
* parameters: mc_rate_control_params.yaml and mc_att_control_params.yaml (e87d6afa),
  imu_gyro_parameters.yaml (21a55362).

The rate law per axis, at the loop period ``dt`` (IMU_GYRO_RATEMAX), with ``w`` the gyro-filtered rate,
``a`` the D-term-filtered derivative of ``w``, ``r`` the rate set-point, ``e = r - w`` (all rad/s):

    u[k] = K P e[k] + i[k] - K D a[k] + FF r[k]
    i[k+1] = clip(i[k] + f(e) K I e[k] dt, -INT_LIM, INT_LIM),   f(e) = max(0, 1 - (e / 400 deg/s)^2)

(the output uses the integrator before its update; ``f`` is PX4's ``i_factor``; while the allocator reports
saturation in one direction the error that would push further into it is zeroed for the integrator). The
derivative acts on the measured rate only: a set-point step gives no derivative kick. Yaw's output then passes
the first-order low-pass at MC_YAW_TQ_CUTOFF. The output is PX4's normalised torque (``vehicle_torque_setpoint``,
nominally [-1, 1]); the allocator, here the vehicle's mixer, saturates it.

Below saturation and for ``|e|`` small against 400 deg/s (``f = 1 - 6e-6`` at 1 deg/s of error), the law is the
LTI system :func:`rate_controller_lti`. PX4 filters the gyro at the sensor's raw rate (often 1-8 kHz) and runs
the controller at IMU_GYRO_RATEMAX; here both run at the loop rate. For the default 40 Hz gyro filter the two
differ by under 0.3 % in gain and 1.2 deg in phase up to 20 Hz (400 Hz against 8 kHz).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import control as ct

from rotorlab.autopilots import filters
from rotorlab.autopilots.params import ParamSpec, ParamTable

__all__ = ["NAME", "FILE_FORMAT", "AXES", "LOOP_RATE_PARAM", "FILTER_GROUPS", "TABLE", "axis_names", "RateController",
           "AttitudeController", "rate_controller_lti", "attitude_controller_lti", "loop_hz"]

NAME = "px4"
FILE_FORMAT = "qgc"  # QGroundControl .params
AXES = ("roll", "pitch", "yaw")
LOOP_RATE_PARAM = "IMU_GYRO_RATEMAX"  # the rate-loop rate, Hz
GYRO_FILTER_PARAM = "IMU_GYRO_CUTOFF"  # the gyro low-pass the rate loop flies on (and the log holds), Hz
#: the filter cutoffs a tuning may move (rotorlab tune --filters search), in groups moved together:
#: the gyro low-pass and the D-term low-pass (one each, all axes)
FILTER_GROUPS = (("IMU_GYRO_CUTOFF",), ("IMU_DGYRO_CUTOFF",))

_RC = "PX4 mc_rate_control_params.yaml @e87d6afa"
_AC = "PX4 mc_att_control_params.yaml @e87d6afa"
_IMU = "PX4 imu_gyro_parameters.yaml @21a55362"

_RATE_NAMES = {
    "roll": dict(P="MC_ROLLRATE_P", I="MC_ROLLRATE_I", D="MC_ROLLRATE_D", FF="MC_ROLLRATE_FF", K="MC_ROLLRATE_K",
                 INT_LIM="MC_RR_INT_LIM", ANG_P="MC_ROLL_P", RATE_MAX="MC_ROLLRATE_MAX"),
    "pitch": dict(P="MC_PITCHRATE_P", I="MC_PITCHRATE_I", D="MC_PITCHRATE_D", FF="MC_PITCHRATE_FF",
                  K="MC_PITCHRATE_K", INT_LIM="MC_PR_INT_LIM", ANG_P="MC_PITCH_P", RATE_MAX="MC_PITCHRATE_MAX"),
    "yaw": dict(P="MC_YAWRATE_P", I="MC_YAWRATE_I", D="MC_YAWRATE_D", FF="MC_YAWRATE_FF", K="MC_YAWRATE_K",
                INT_LIM="MC_YR_INT_LIM", ANG_P="MC_YAW_P", RATE_MAX="MC_YAWRATE_MAX"),
}


def _axis_specs(axis, p_min, p_max, p_def, i_def, d_max, d_def):
    n = _RATE_NAMES[axis]
    return [
        ParamSpec(n["P"], "norm/(rad/s)", p_min, p_max, p_def,
                  f"{axis} rate P gain: normalised torque per rad/s of rate error (scaled by {n['K']})", _RC),
        ParamSpec(n["I"], "norm/rad", 0.0, None, i_def,
                  f"{axis} rate I gain: integrator growth per rad of integrated rate error (scaled by {n['K']})", _RC),
        ParamSpec(n["D"], "norm/(rad/s^2)", 0.0, d_max, d_def,
                  f"{axis} rate D gain on the filtered derivative of the measured rate (scaled by {n['K']})", _RC),
        ParamSpec(n["FF"], "norm/(rad/s)", 0.0, None, 0.0,
                  f"{axis} rate feed-forward: normalised torque per rad/s of rate set-point (not scaled by K)", _RC),
        ParamSpec(n["K"], "1", 0.01, 5.0, 1.0,
                  f"{axis} rate controller gain K multiplying P, I and D (K = 1: parallel form)", _RC),
        ParamSpec(n["INT_LIM"], "norm", 0.0, None, 0.3, f"{axis} rate integrator limit (normalised torque)", _RC),
    ]


TABLE = ParamTable(NAME, [
    *_axis_specs("roll", 0.01, 0.5, 0.15, 0.2, 0.01, 0.003),
    *_axis_specs("pitch", 0.01, 0.6, 0.15, 0.2, None, 0.003),
    *_axis_specs("yaw", 0.0, 0.6, 0.2, 0.1, None, 0.0),
    ParamSpec("MC_YAW_TQ_CUTOFF", "Hz", 0.0, 10.0, 2.0,
              "cutoff of the first-order low-pass on the yaw torque set-point (0: off)", _RC),
    ParamSpec("MC_ROLL_P", "1/s", 0.0, 12.0, 4.0, "roll angle P gain: rate set-point (rad/s) per rad of error", _AC),
    ParamSpec("MC_PITCH_P", "1/s", 0.0, 12.0, 4.0, "pitch angle P gain: rate set-point (rad/s) per rad of error", _AC),
    ParamSpec("MC_YAW_P", "1/s", 0.0, 5.0, 2.8, "yaw angle P gain: rate set-point (rad/s) per rad of error", _AC),
    ParamSpec("MC_YAW_WEIGHT", "1", 0.0, 1.0, 0.4,
              "weight of yaw against roll and pitch in the quaternion attitude error (no effect on the yaw gain)", _AC),
    ParamSpec("MC_ROLLRATE_MAX", "deg/s", 0.0, 1800.0, 220.0, "limit of the roll rate set-point", _AC),
    ParamSpec("MC_PITCHRATE_MAX", "deg/s", 0.0, 1800.0, 220.0, "limit of the pitch rate set-point", _AC),
    ParamSpec("MC_YAWRATE_MAX", "deg/s", 0.0, 1800.0, 200.0, "limit of the yaw rate set-point", _AC),
    ParamSpec("IMU_GYRO_CUTOFF", "Hz", 0.0, 1000.0, 40.0,
              "cutoff of the second-order Butterworth low-pass on the gyro sent to the controllers (0: off)", _IMU),
    ParamSpec("IMU_DGYRO_CUTOFF", "Hz", 0.0, 1000.0, 20.0,
              "cutoff of the second-order Butterworth low-pass on the rate derivative, the D-term filter (0: off)",
              _IMU),
    ParamSpec("IMU_GYRO_RATEMAX", "Hz", 100, 2000, 400,
              "rate-controller loop rate (PX4 offers 100, 250, 400, 800, 1000, 2000 Hz)", _IMU, integer=True),
])

_I_FACTOR_RAD_S = math.radians(400.0)
_AXIS_INDEX = (0, 1, 2)
_NO_FLAGS = (False, False, False)  # no saturation reported
_NEAR_1 = 1 - 1e-5  # PX4's bound on the tilt rotation's x or y part: beyond it a near half turn, the set-point kept


def axis_names(axis: str) -> dict[str, str]:
    """The parameter names of one axis by role: ``P, I, D, FF, K, INT_LIM, ANG_P, RATE_MAX``."""
    return dict(_RATE_NAMES[_axis(axis)])


def _axis(axis: str) -> str:
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
    return axis


def loop_hz(params: Mapping[str, float]) -> float:
    """The rate loop's rate, Hz (IMU_GYRO_RATEMAX, default 400)."""
    return float(params.get(LOOP_RATE_PARAM, TABLE[LOOP_RATE_PARAM].default))


def _gains(params, axis):
    n = _RATE_NAMES[axis]
    k = float(params[n["K"]])
    return (k * float(params[n["P"]]), k * float(params[n["I"]]), k * float(params[n["D"]]), float(params[n["FF"]]),
            float(params[n["INT_LIM"]]))


def rate_controller_lti(params: Mapping[str, float], axis: str, dt_s: float,
                        gyro_filter: bool = True, fixed_structure: bool = False) -> ct.StateSpace:
    """PX4's rate law of one axis as a discrete LTI system at the loop period ``dt_s``.

    Inputs ``["rate_sp", "rate"]`` (rad/s), output ``["torque"]`` (normalised). ``rate`` is the raw gyro when
    ``gyro_filter`` (the IMU_GYRO_CUTOFF filter is part of the system), or a rate that has already been through it
    (``gyro_filter=False``, e.g. PX4's logged ``vehicle_angular_velocity``). Valid below saturation and with the
    integrator inside its limit; equals :class:`RateController` there (``i_factor`` = 1). With
    ``fixed_structure`` the I and D paths keep their states at zero gain, so the realisation depends on the
    filter parameters only and its matrices are affine in ``(K P, K I, K D, FF)``: the form a structured tuner
    varies (the default drops the states of a zero gain, which would otherwise leave an unobservable pole at
    ``z = 1`` for ``I = 0``).

    Parameters
    ----------
    params : mapping
        PX4 parameters by name (see :data:`TABLE`); the axis's gains, MC_YAW_TQ_CUTOFF, IMU_GYRO_CUTOFF and
        IMU_DGYRO_CUTOFF are read.
    axis : {"roll", "pitch", "yaw"}
    dt_s : float
        Loop period, s (1 / IMU_GYRO_RATEMAX on the vehicle).

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> C = px4.rate_controller_lti(px4.TABLE.defaults(), "roll", 1 / 400)
    >>> C.input_labels, C.output_labels
    (['rate_sp', 'rate'], ['torque'])
    """
    axis = _axis(axis)
    fs = 1.0 / dt_s
    kp, ki, kd, ff, _ = _gains(params, axis)
    G = filters.butter2_ss(fs, float(params["IMU_GYRO_CUTOFF"])) if gyro_filter else ct.ss([], [], [], [[1.0]], dt_s)
    # [r, y] -> [r, w]
    pre = ct.append(ct.ss([], [], [], [[1.0]], dt_s), G)
    parts = [ct.ss([], [], [], [[kp + ff, -kp]], dt_s)]
    if ki or fixed_structure:
        # i[k+1] = i[k] + ki dt e[k], output i[k]: ki dt / (z - 1) on e = r - w
        parts.append(ct.ss([[1.0]], [[ki * dt_s, -ki * dt_s]], [[1.0]], [[0.0, 0.0]], dt_s))
    if kd or fixed_structure:
        # a = Dlpf((w[k] - w[k-1]) / dt); state: w[k-1]
        diff = ct.ss([[0.0]], [[1.0]], [[-1.0 / dt_s]], [[1.0 / dt_s]], dt_s)
        Dl = filters.butter2_ss(fs, float(params["IMU_DGYRO_CUTOFF"]))
        dpath = ct.series(diff, Dl)
        parts.append(ct.series(ct.ss([], [], [], [[0.0, 1.0]], dt_s), dpath, ct.ss([], [], [], [[-kd]], dt_s)))
    core = parts[0]
    for p in parts[1:]:
        core = ct.parallel(core, p)
    C = ct.series(pre, core)
    if axis == "yaw":
        C = ct.series(C, filters.alpha_ss(dt_s, float(params["MC_YAW_TQ_CUTOFF"])))
    return ct.ss(C.A, C.B, C.C, C.D, dt_s, inputs=["rate_sp", "rate"], outputs=["torque"],
                 name=f"px4_rate_{axis}")


def attitude_controller_lti(params: Mapping[str, float], axis: str, dt_s: float) -> ct.StateSpace:
    """PX4's attitude law of one axis, linearised at zero error: ``rate_sp = ANG_P (angle_sp - angle)``.

    Inputs ``["angle_sp", "angle"]`` (rad), output ``["rate_sp"]`` (rad/s); below the rate limit. The yaw weight
    drops out of the linear law (PX4 divides MC_YAW_P by MC_YAW_WEIGHT to undo the weight's scaling of the error).

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> float(px4.attitude_controller_lti(px4.TABLE.defaults(), "yaw", 0.0025).D[0, 0])
    2.8
    """
    p = float(params[_RATE_NAMES[_axis(axis)]["ANG_P"]])
    return ct.ss([], [], [], [[p, -p]], dt_s, inputs=["angle_sp", "angle"], outputs=["rate_sp"],
                 name=f"px4_att_{axis}")


class RateController:
    """PX4's three-axis rate law as the flight software runs it, one call per loop tick.

    Plain floats per axis: a tick costs a few microseconds, where numpy's per-call overhead on 3-vectors would
    cost several times the arithmetic.

    Parameters
    ----------
    params : mapping
        PX4 parameters by name (complete for the rate law: :meth:`ParamTable.complete`).
    dt_s : float
        Loop period, s.
    gyro_filter : bool
        Run the IMU_GYRO_CUTOFF filter on the ``rate`` given to :meth:`step` (False when it is already filtered).

    Attributes
    ----------
    integral : list of float
        The integrator, per axis (normalised torque; PX4's ``rate_ctrl_status`` ``*speed_integ``).
    rate_error : list of float
        The last tick's rate error ``r - w``, rad/s.

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> rc = px4.RateController(px4.TABLE.defaults(), 1 / 400)
    >>> [round(v, 4) for v in rc.step([0.1, 0.0, 0.0], [0.0, 0.0, 0.0])]  # P kick, no D kick
    [0.015, 0.0, 0.0]
    """

    def __init__(self, params: Mapping[str, float], dt_s: float, gyro_filter: bool = True):
        self.dt = float(dt_s)
        self._gains = [_gains(params, a) for a in AXES]
        fs = 1.0 / self.dt
        bg, ag = filters.butter2_coeffs(fs, float(params["IMU_GYRO_CUTOFF"]) if gyro_filter else 0.0)
        bd, ad = filters.butter2_coeffs(fs, float(params["IMU_DGYRO_CUTOFF"]))
        self._gyro = (*(float(v) for v in bg), float(ag[1]), float(ag[2]))
        self._dterm = (*(float(v) for v in bd), float(ad[1]), float(ad[2]))
        self._yaw_alpha = filters.alpha_lowpass(self.dt, float(params["MC_YAW_TQ_CUTOFF"]))
        self.reset()

    def reset(self) -> None:
        """Zero the integrator and every filter (PX4 at arming)."""
        # direct form II states (w[k-1], w[k-2]) of the gyro and D-term filters, per axis
        self._g = [[0.0, 0.0] for _ in AXES]
        self._d = [[0.0, 0.0] for _ in AXES]
        self._w_prev = [0.0, 0.0, 0.0]
        self._yaw_y = 0.0
        self.integral = [0.0, 0.0, 0.0]
        self.rate_error = [0.0, 0.0, 0.0]

    def step(self, rate_sp, rate, sat_pos=None, sat_neg=None, landed: bool = False) -> tuple:
        """One tick: normalised torque ``(roll, pitch, yaw)`` from the set-point and the gyro (rad/s).

        ``sat_pos`` / ``sat_neg`` (bool per axis) are the allocator's saturation flags; ``landed`` freezes the
        integrator. The output is not clipped (the mixer saturates).
        """
        # it runs every tick: each axis's gains and filter states come out of one zip (no indexing per use), and
        # an axis with D = 0 skips its D-term filter, whose output it would multiply by zero (an exact zero
        # changes no sum but, at most, the sign of a zero output)
        gb0, gb1, gb2, ga1, ga2 = self._gyro
        db0, db1, db2, da1, da2 = self._dterm
        dt = self.dt
        integral, rate_error, w_prev = self.integral, self.rate_error, self._w_prev
        out = []
        for i, r, y, (kp, ki, kd, ff, lim), g, d, s_pos, s_neg in zip(
                _AXIS_INDEX, rate_sp, rate, self._gains, self._g, self._d,
                _NO_FLAGS if sat_pos is None else sat_pos, _NO_FLAGS if sat_neg is None else sat_neg):
            g0, g1 = g
            x0 = y - ga1 * g0 - ga2 * g1
            w = gb0 * x0 + gb1 * g0 + gb2 * g1
            g[0], g[1] = x0, g0
            e = r - w
            rate_error[i] = e
            integ = integral[i]
            if kd:
                d0, d1 = d
                x0 = (w - w_prev[i]) / dt - da1 * d0 - da2 * d1
                d[0], d[1] = x0, d0
                w_prev[i] = w
                out.append(kp * e + integ - kd * (db0 * x0 + db1 * d0 + db2 * d1) + ff * r)
            else:
                out.append(kp * e + integ + ff * r)
            if not landed:
                if s_pos and e > 0.0:
                    e = 0.0
                if s_neg and e < 0.0:
                    e = 0.0
                f = e / _I_FACTOR_RAD_S
                f = 1.0 - f * f
                nxt = integ + (f if f > 0.0 else 0.0) * ki * e * dt
                if nxt - nxt == 0.0:  # finite (inf - inf and NaN give NaN): math.isfinite without a call
                    integral[i] = lim if nxt > lim else (-lim if nxt < -lim else nxt)
        self._yaw_y += self._yaw_alpha * (out[2] - self._yaw_y)
        out[2] = self._yaw_y
        return tuple(out)


def _canonical(q):
    # the one of q, -q whose first non-zero component is positive (PX4 Quaternion::canonical)
    for c in q:
        if c != 0.0:
            return q if c > 0 else (-q[0], -q[1], -q[2], -q[3])
    return q


class AttitudeController:
    """PX4's quaternion attitude law (AttitudeControl.cpp): rate set-point from attitude and its set-point.

    The desired attitude is first reduced to the tilt that aligns the thrust axis (the shortest rotation of the
    body z axis onto the desired one), then the yaw part of the remaining rotation is scaled by MC_YAW_WEIGHT; the
    error is ``2 imag(canonical(q^-1 q_d))`` (sin of half the angle times the axis, times 2), multiplied per axis by
    MC_ROLL_P, MC_PITCH_P and MC_YAW_P / MC_YAW_WEIGHT, plus the world-z yaw-rate feed-forward, and each axis is
    limited to MC_*RATE_MAX. Quaternions are ``(w, x, y, z)``, body to world (FRD body, NED world as PX4).

    Examples
    --------
    >>> import math
    >>> from rotorlab.autopilots import px4
    >>> att = px4.AttitudeController(px4.TABLE.defaults())
    >>> h = 0.05  # half of a 0.1 rad roll set-point
    >>> [round(v, 4) for v in att.update((1, 0, 0, 0), (math.cos(h), math.sin(h), 0, 0))]
    [0.3998, 0.0, 0.0]
    """

    def __init__(self, params: Mapping[str, float]):
        w = min(max(float(params["MC_YAW_WEIGHT"]), 0.0), 1.0)
        p = [float(params["MC_ROLL_P"]), float(params["MC_PITCH_P"]), float(params["MC_YAW_P"])]
        if w > 1e-4:
            p[2] /= w
        self.yaw_w, self.p = w, tuple(p)
        self.rate_limit = tuple(math.radians(float(params[n])) for n in
                                ("MC_ROLLRATE_MAX", "MC_PITCHRATE_MAX", "MC_YAWRATE_MAX"))

    def update(self, q, q_sp, yawspeed_sp: float = float("nan")) -> tuple:
        """Body rate set-point ``(p, q, r)``, rad/s, from the attitude ``q`` and its set-point ``q_sp``."""
        # written out in floats in one body (it runs every tick: a helper call per quaternion product costs as much
        # as the product), in PX4's order of operations: Quaternion products, inverses (conjugate over the squared
        # norm), Dcm z columns and the shortest arc as PX4's Quatf functions compute them
        qw, qx, qy, qz = q
        dw, dx, dy, dz = q_sp
        # the body z axis (third column of the rotation matrix) of q and of q_sp (2.0: exactly 2, float * float)
        sx, sy, sz = 2.0 * (qw * qy + qx * qz), 2.0 * (qy * qz - qw * qx), qw * qw - qx * qx - qy * qy + qz * qz
        tx, ty, tz = 2.0 * (dw * dy + dx * dz), 2.0 * (dy * dz - dw * dx), dw * dw - dx * dx - dy * dy + dz * dz
        # the smallest rotation taking the one onto the other
        cx, cy, cz = sy * tz - sz * ty, sz * tx - sx * tz, sx * ty - sy * tx
        dot = sx * tx + sy * ty + sz * tz
        if dot < 0.0 and math.sqrt(cx * cx + cy * cy + cz * cz) < 1e-5:  # the cheap test first: both are needed
            # opposite directions: a half turn about an axis normal to the body z axis
            ox, oy, oz = (1.0, 0.0, 0.0) if abs(sx) < 0.9 else (0.0, 1.0, 0.0)
            w, x, y, z = 0.0, sy * oz - sz * oy, sz * ox - sx * oz, sx * oy - sy * ox
        else:
            w, x, y, z = dot + math.sqrt((sx * sx + sy * sy + sz * sz) * (tx * tx + ty * ty + tz * tz)), cx, cy, cz
        n = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        if x > _NEAR_1 or x < -_NEAR_1 or y > _NEAR_1 or y < -_NEAR_1:  # |x| or |y| > 1 - 1e-5, no abs() calls
            rw, rx, ry, rz = dw, dx, dy, dz
        else:  # the tilt rotation times q: the attitude of thrust aligned, yaw kept
            rw, rx, ry, rz = (w * qw - x * qx - y * qy - z * qz, w * qx + x * qw + y * qz - z * qy,
                              w * qy - x * qz + y * qw + z * qx, w * qz + x * qy - y * qx + z * qw)
        # q_mix = canonical(qd_red^-1 q_sp): only its w and z parts are read, and its x and y only decide the sign
        # where w is zero (canonical)
        n = rw * rw + rx * rx + ry * ry + rz * rz
        w, x, y, z = rw / n, -rx / n, -ry / n, -rz / n
        mw, mz = w * dw - x * dx - y * dy - z * dz, w * dz + x * dy - y * dx + z * dw
        if not mw > 0.0:
            mw, _, _, mz = _canonical((mw, w * dx + x * dw + y * dz - z * dy, w * dy - x * dz + y * dw + z * dx, mz))
        c0 = -1.0 if mw < -1.0 else (1.0 if mw > 1.0 else mw)  # min(max(v, -1), 1), a NaN kept
        c3 = -1.0 if mz < -1.0 else (1.0 if mz > 1.0 else mz)
        yw = self.yaw_w
        ew, ez = math.cos(yw * math.acos(c0)), math.sin(yw * math.asin(c3))
        # q_d = qd_red (ew, 0, 0, ez): the general product's terms with a zero factor left out (a zero product
        # changes no non-zero sum; at most the sign of an exact zero)
        dw, dx, dy, dz = rw * ew - rz * ez, rx * ew + ry * ez, -rx * ez + ry * ew, rw * ez + rz * ew
        # q_e = canonical(q^-1 q_d)
        n = qw * qw + qx * qx + qy * qy + qz * qz
        w, x, y, z = qw / n, -qx / n, -qy / n, -qz / n
        e = (w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
             w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw)
        _, ex, ey, ez = e if e[0] > 0.0 else _canonical(e)
        p0, p1, p2 = self.p
        r0, r1, r2 = 2.0 * ex * p0, 2.0 * ey * p1, 2.0 * ez * p2
        if yawspeed_sp == yawspeed_sp and abs(yawspeed_sp) != math.inf:
            # the world z axis in the body: the third column of the rotation matrix of q^-1
            z0, z1, z2 = 2.0 * (w * y + x * z), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z
            r0, r1, r2 = r0 + z0 * yawspeed_sp, r1 + z1 * yawspeed_sp, r2 + z2 * yawspeed_sp
        l0, l1, l2 = self.rate_limit
        return (l0 if r0 > l0 else (-l0 if r0 < -l0 else r0), l1 if r1 > l1 else (-l1 if r1 < -l1 else r1),
                l2 if r2 > l2 else (-l2 if r2 < -l2 else r2))
