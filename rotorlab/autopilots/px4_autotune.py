"""PX4's multicopter autotune: the on-line identification and the rate PID and attitude P that
``mc_autotune_attitude_control`` computes from it, written from PX4's source as formulas (a baseline to compare
tuned gains against).

Sources (PX4-Autopilot main, the released module v1.13-v1.16):

* src/lib/pid_design/pid_design.hpp, ``computePidGmvc``: generalised minimum-variance PID (Yamamoto, Fujii &
  Kaneda 1998) with PX4's extra division of the integral gain by 5; its test pid_design_test.cpp;
* src/lib/system_identification/system_identification.cpp and arx_rls.hpp: the band-pass filters on both
  signals and the recursive least squares of the ARX model ``ArxRls<2, 2, 1>``;
* src/modules/mc_autotune_attitude_control/mc_autotune_attitude_control.cpp: the model sample time
  (``checkFilters``), the input scaling, the identification signal (``getIdentificationSignal``), the
  convergence test and axis sequence (``updateStateMachine``), the design arguments, the attitude gain rule,
  the gain check (``areGainsGood``) and the parallel-form parameters (``saveGainsToParams``);
* mc_autotune_attitude_control_params.c: MC_AT_RISE_TIME (0.01-0.5 s, default 0.14 s), MC_AT_SYSID_AMP
  (default 0.7);
* src/modules/mc_att_control/mc_att_control_main.cpp: the identification signal is added to the attitude
  controller's rate set-point.

What the module does, per axis in turn (roll, pitch, yaw), flying the current gains: it adds a washed-out step
signal to the rate set-point (:class:`StepSignal`), band-passes the torque set-point and the gyro-filtered rate
at the loop rate, fits the ARX model ``A(q^-1) y[k] = q^-1 B(q^-1) u[k]`` (``A = 1 + a1 q^-1 + a2 q^-2``,
``B = b0 + b1 q^-1 + b2 q^-2``) by recursive least squares at the model sample time :func:`model_dt`
(:class:`SystemIdentification`), and when the estimate has converged keeps the gains designed from it
(:func:`identify_axis`). The design (:func:`design`), with ``rho = dt / sigma`` (``sigma`` the rise time
MC_AT_RISE_TIME, 0.2 s on yaw), ``mu = 0.25 (1 - delta) + 0.51 delta`` (damping index ``delta = 0``) and
detuning ``lambda = 0.7``::

    p1 = -2 exp(-rho / (2 mu)) cos(sqrt(4 mu - 1) rho / (2 mu)),   p2 = exp(-rho / mu)
    e1 = -a1 + p1 + 1
    f0 = -a1 e1 + a1 - a2 + e1 + p2,   f1 = a1 e1 - a2 e1 + a2,   f2 = a2 e1
    nu = lambda + (e1 + 1)(b0 + b1 + b2)
    kc = -(f1 + 2 f2) / nu,   ki = -(f0 + f1 + f2) / (dt (f1 + 2 f2)) / 5,   kd = -dt f2 / (f1 + 2 f2)

a slightly negative ``kd`` (above -0.001) set to 0, and the attitude gain from "an error of 60 deg gives full
output", ``clip(1 / (60 deg x kc), 2, 6.5)``. After the three axes it checks the set (:func:`check_gains`:
``0 < kc < 0.5``, ``0 < ki < 10``, ``0 <= kd < 0.1``, ``0 < att_p < 12`` on every axis) and saves all three
axes or none, in the parallel form ``MC_*RATE_P = kc``, ``MC_*RATE_K = 1``, ``MC_*RATE_I = kc ki``,
``MC_*RATE_D = kc kd``, ``MC_*_P = att_p`` (:func:`autotune_params`).

The module's ARX model has one sample of delay and three input taps at the model period (8-10 ms at the
default 40 Hz gyro filter), so it represents at most about three model periods of delay between the torque
set-point and the filtered rate; a vehicle with a longer actuator delay gets the best such fit to its
closed-loop band-passed data, and the rule designs for that fit.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import numpy as np

from rotorlab.autopilots import px4
from rotorlab.errors import DataError

__all__ = ["gmvc_pid", "model_dt", "arx221_fit", "StepSignal", "ArxRls", "SystemIdentification", "AxisResult", "design",
           "identify_axis", "check_gains", "autotune_params", "autotune_gains", "RISE_TIME_DEFAULT_S",
           "YAW_RISE_TIME_S", "SYSID_AMP_DEFAULT"]

RISE_TIME_DEFAULT_S = 0.14  # MC_AT_RISE_TIME default
RISE_TIME_RANGE_S = (0.01, 0.5)  # MC_AT_RISE_TIME documented range
YAW_RISE_TIME_S = 0.2  # the module's fixed yaw rise time
SYSID_AMP_DEFAULT = 0.7  # MC_AT_SYSID_AMP default, rad/s of rate set-point
_MODEL_DT_MIN_S, _MODEL_DT_MAX_S = 2e-3, 10e-3
PUBLISH_S = 0.1  # the module's publishing (design, signal, state machine) period
SIGNAL_TAU_S = 0.2  # wash-out time constant of the identification signal
HPF_HZ = 0.5  # identification high-pass
FORGET_TAU_S = 60.0  # RLS forgetting time constant
CONVERGED_VARIANCE = 50.0  # every coefficient variance below it: converged
MIN_AXIS_S, TIMEOUT_S = 5.0, 20.0  # shortest identification of an axis, and the abort time


def gmvc_pid(num, den, dt_s: float, rise_time_s: float = 0.1, damping: float = 1.0,
             detune: float = 0.5) -> tuple[float, float, float]:
    """PX4's ``computePidGmvc``: ``(kc, ki, kd)`` of ``u = kc (e + ki integral(e) + kd de/dt)`` for the ARX model
    ``num = (b0, b1, b2)``, ``den = (1, a1, a2)`` at ``dt_s``. Arguments are clamped as PX4 clamps them
    (rise time 0.01-1 s, damping 0-1, detune 0-10); a model with ``nu = 0`` gives zeros.

    Examples
    --------
    >>> [round(v, 4) for v in gmvc_pid((0.0098, -0.162, 0.147), (1.0, -1.814, 0.822), 0.004, 0.1, 1.0, 0.5)]
    [0.1292, 2.3823, 0.0463]
    """
    sigma = min(max(float(rise_time_s), 0.01), 1.0)
    delta = min(max(float(damping), 0.0), 1.0)
    lbda = min(max(float(detune), 0.0), 10.0)
    a1, a2 = float(den[1]), float(den[2])
    b0, b1, b2 = (float(v) for v in num)
    rho = dt_s / sigma
    mu = 0.25 * (1.0 - delta) + 0.51 * delta
    p1 = -2.0 * math.exp(-rho / (2.0 * mu)) * math.cos(math.sqrt(4.0 * mu - 1.0) * rho / (2.0 * mu))
    p2 = math.exp(-rho / mu)
    e1 = -a1 + p1 + 1.0
    f0 = -a1 * e1 + a1 - a2 + e1 + p2
    f1 = a1 * e1 - a2 * e1 + a2
    f2 = a2 * e1
    nu = lbda + (e1 + 1.0) * (b0 + b1 + b2)
    if abs(nu) < np.finfo(np.float32).eps:
        return 0.0, 0.0, 0.0
    den_i = np.float64(f1 + 2.0 * f2)
    with np.errstate(divide="ignore", invalid="ignore"):  # IEEE results, as PX4's float arithmetic gives them
        kc = -(f1 + 2.0 * f2) / nu
        ki = -(f0 + f1 + f2) / (dt_s * den_i) / 5.0
        kd = -dt_s * f2 / den_i
    return float(kc), float(ki), float(kd)


def model_dt(imu_gyro_cutoff_hz: float, loop_dt_s: float) -> float:
    """The autotune model's sample time, s: ``1 / (2 IMU_GYRO_CUTOFF)`` (at least the loop period), clamped to
    2-10 ms, then rounded down to a whole number of loop periods.

    Examples
    --------
    >>> model_dt(40.0, 0.0025)  # 1 / 80 Hz = 12.5 ms, clamped to 10 ms = 4 loop periods
    0.01
    >>> model_dt(100.0, 0.0025)
    0.005
    """
    half_period = 1.0 / (2.0 * imu_gyro_cutoff_hz) if imu_gyro_cutoff_hz > 0 else math.inf
    dt = min(max(max(half_period, loop_dt_s), _MODEL_DT_MIN_S), _MODEL_DT_MAX_S)
    return max(int(dt / loop_dt_s), 1) * loop_dt_s


def arx221_fit(u, y) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ARX model ``y[k] = -a1 y[k-1] - a2 y[k-2] + b0 u[k-1] + b1 u[k-2] + b2 u[k-3]`` (PX4's
    ``ArxRls<2, 2, 1>``) from samples at the model rate; returns ``(num, den) = ((b0, b1, b2), (1, a1, a2))``.

    Raises
    ------
    rotorlab.errors.DataError
        Fewer samples than unknowns, or a regressor without excitation (rank-deficient).
    """
    u = np.asarray(u, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if u.shape != y.shape or u.size < 10:
        raise DataError(f"ARX fit needs equally long u and y of at least 10 samples, got {u.size} and {y.size}")
    k = np.arange(3, u.size)
    Phi = np.column_stack([-y[k - 1], -y[k - 2], u[k - 1], u[k - 2], u[k - 3]])
    theta, _, rank, _ = np.linalg.lstsq(Phi, y[k], rcond=None)
    if rank < 5:
        raise DataError(f"ARX fit: the data excite {rank} of the 5 coefficients (the input needs more excitation)")
    a1, a2, b0, b1, b2 = theta
    return np.array([b0, b1, b2]), np.array([1.0, a1, a2])


class StepSignal:
    """PX4's identification signal, one value per publishing tick (:data:`PUBLISH_S`): a rate set-point (rad/s)
    that steps between 0 and ``amplitude``, washed out by a first-order filter of time constant 0.2 s run at the
    tick rate (``step - alpha-filtered step``, ``alpha = 0.1 / (0.2 + 0.1)``). The first step lasts 6 ticks, the
    next ones 10, 9, ..., 2 ticks, then 6, 5, 4, 3, 2 ticks over and over (mc_autotune_attitude_control.cpp
    ``getIdentificationSignal``: ``_steps_counter`` starts at 5, ``_max_steps`` at 10, counts down to 1 and
    restarts at 5).

    Examples
    --------
    >>> s = StepSignal(0.7)
    >>> [round(s.next(), 4) for _ in range(8)]
    [0.7, 0.4667, 0.3111, 0.2074, 0.1383, 0.0922, -0.6385, -0.4257]
    """

    def __init__(self, amplitude: float):
        self.amplitude = float(amplitude)
        self._counter, self._max, self._sign, self._state = 5, 10, 1, 0.0
        self._alpha = PUBLISH_S / (SIGNAL_TAU_S + PUBLISH_S)

    def next(self) -> float:
        if self._counter > self._max:
            self._sign = 0 if self._sign == 1 else 1
            self._counter = 0
            self._max = self._max - 1 if self._max > 1 else 5
        self._counter += 1
        step = self._sign * self.amplitude
        out = step - self._state
        self._state += self._alpha * (step - self._state)
        return out


class ArxRls:
    """PX4's ``ArxRls<2, 2, 1>`` (src/lib/system_identification/arx_rls.hpp): recursive least squares of the ARX
    model of :func:`arx221_fit`, coefficients ``theta = (a1, a2, b0, b1, b2)`` from zero, covariance from
    ``1e4 I``, forgetting factor ``lam``. A sample enters the input and output buffers; the recursion starts once
    they hold six samples (no initial zeros in the regressor ``[-y[k-1], -y[k-2], u[k-1], u[k-2], u[k-3]]``):
    ``P <- (P - P phi phi' P / (lam + phi' P phi)) / lam``, ``theta <- theta + P phi (y[k] - phi' theta)``.

    Examples
    --------
    >>> r = ArxRls()
    >>> for u, y in [(0, 0)] * 5 + [(1, 2), (3, 4), (5, 6), (7, 8)]:
    ...     r.update(u, y)
    >>> [round(float(v), 3) for v in r.theta]  # arx_rls_test.cpp test221: -1.81, 1.06, 0.38, -0.27, 0.26 (+-1e-2)
    [-1.811, 1.056, 0.377, -0.264, 0.264]
    """

    def __init__(self, lam: float = 1.0):
        self.lam = float(lam)
        self.theta = np.zeros(5)
        self.P = np.eye(5) * 10e3
        self._u = np.zeros(4)
        self._y = np.zeros(3)
        self._n = 0

    def update(self, u: float, y: float) -> None:
        self._u[:3] = self._u[1:]
        self._u[3] = u
        self._y[:2] = self._y[1:]
        self._y[2] = y
        if self._n <= 5:
            self._n += 1
        if self._n <= 5:
            return
        phi = np.array([-self._y[1], -self._y[0], self._u[2], self._u[1], self._u[0]])
        Pphi = self.P @ phi
        self.P = (self.P - np.outer(Pphi, Pphi) / (self.lam + phi @ Pphi)) / self.lam
        self.theta = self.theta + self.P @ phi * (self._y[2] - phi @ self.theta)

    @property
    def variances(self) -> np.ndarray:
        return np.diag(self.P).copy()


class SystemIdentification:
    """PX4's on-line identification of one axis (src/lib/system_identification/system_identification.cpp): torque
    ``u`` and rate ``y`` low-passed at the gyro cutoff (``LowPassFilter2p``) and high-passed at 0.5 Hz
    (``h[k] = a (h[k-1] + x[k] - x[k-1])``, ``a = f_s / (f_s + pi)``) at the loop rate by
    :meth:`update_filters`, and the band-passed pair fed to :class:`ArxRls` (forgetting ``1 - model_dt / 60 s``)
    by :meth:`update`, which the module calls once per model period. The first sample only initialises the
    filters. ``hpf_hz`` and ``forget_tau_s`` are the module's (0.5 Hz, 60 s) unless given (PX4's unit tests use
    others).
    """

    def __init__(self, loop_dt_s: float, gyro_cutoff_hz: float, model_dt_s: float, *, hpf_hz: float = HPF_HZ,
                 forget_tau_s: float = FORGET_TAU_S):
        from rotorlab.autopilots import filters

        self._b, self._a = filters.butter2_coeffs(1.0 / loop_dt_s, gyro_cutoff_hz)
        self._alpha_hp = (1.0 / loop_dt_s) / (1.0 / loop_dt_s + 2.0 * math.pi * hpf_hz)
        self.rls = ArxRls(1.0 - model_dt_s / forget_tau_s)
        self._w = np.zeros((2, 2))  # direct-form II delay elements of the u and y low-passes
        self._hp = np.zeros(2)
        self._prev = np.zeros(2)
        self.initialised = False

    def update_filters(self, u: float, y: float) -> None:
        x = np.array([u, y], float)
        if not self.initialised:
            self._w[:] = (x / self._b.sum())[:, None]  # LowPassFilter2p::reset: output = the sample
            self._hp[:] = 0.0
            self._prev = x
            self.initialised = True
            return
        w0 = x - self._w[:, 0] * self._a[1] - self._w[:, 1] * self._a[2]
        lp = w0 * self._b[0] + self._w[:, 0] * self._b[1] + self._w[:, 1] * self._b[2]
        self._w[:, 1] = self._w[:, 0]
        self._w[:, 0] = w0
        self._hp = self._alpha_hp * self._hp + self._alpha_hp * (lp - self._prev)
        self._prev = lp

    def update(self) -> None:
        self.rls.update(self._hp[0], self._hp[1])

    @property
    def theta(self) -> np.ndarray:
        return self.rls.theta

    @property
    def variances(self) -> np.ndarray:
        return self.rls.variances


@dataclasses.dataclass
class AxisResult:
    """What the module holds for one axis when it moves on: the ARX model ``(num, den)`` at ``model_dt_s`` in
    the vehicle's units (normalised torque -> rad/s), the standard-form gains ``kc, ki, kd`` and the attitude
    gain ``att_p`` it copies, and ``time_s``, the time the axis took (from its start to convergence)."""

    axis: str
    num: np.ndarray
    den: np.ndarray
    model_dt_s: float
    kc: float
    ki: float
    kd: float
    att_p: float
    time_s: float


def design(num, den, model_dt_s: float, rise_time_s: float) -> tuple[float, float, float, float]:
    """The module's design from one model: :func:`gmvc_pid` with ``damping = 0`` and ``detune = 0.7``, a ``kd``
    in (-0.001, 0) set to 0, and the attitude gain ``clip(1 / (60 deg x kc), 2, 6.5)`` ("an error of 60 deg
    gives full output"). Returns ``(kc, ki, kd, att_p)`` (standard form, see :func:`gmvc_pid`).

    Examples
    --------
    >>> [round(v, 4) for v in design((0.02, 0.01, 0.0), (1.0, -1.6, 0.64), 0.005, 0.14)]
    [0.0909, 2.7808, 0.0345, 6.5]
    """
    kc, ki, kd = gmvc_pid(num, den, model_dt_s, rise_time_s, 0.0, 0.7)
    if -0.001 < kd < 0.0:
        kd = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        att_p = float(np.clip(1.0 / (math.radians(60.0) * np.float64(kc)), 2.0, 6.5))
    return kc, ki, kd, att_p


def identify_axis(loop: Callable[[float], tuple[float, float]], axis: str, loop_dt_s: float,
                  gyro_cutoff_hz: float, input_scale: float, *, amplitude: float = SYSID_AMP_DEFAULT,
                  rise_time_s: float = RISE_TIME_DEFAULT_S) -> AxisResult:
    """Run the module's identification of ``axis`` on a closed loop and return what it copies at convergence.

    ``loop(rate_sp)`` advances the vehicle flying its current gains by one loop period with the identification
    signal ``rate_sp`` (rad/s) added to the attitude controller's rate set-point, and returns the torque
    set-point (normalised) and the gyro-filtered rate (rad/s, PX4's ``vehicle_angular_velocity``) of that
    period. The module (mc_autotune_attitude_control.cpp ``Run``, ``updateStateMachine``): filters every
    sample of ``input_scale x torque`` (``1 / (MC_*RATE_P MC_*RATE_K)``, scaled back out of the model) and
    the rate, updates the model once per :func:`model_dt`, and on each publishing tick (the first loop period
    more than 100 ms after the last) first checks convergence (every coefficient variance below 50 and more
    than 5 s on the axis: it then copies the gains designed at the previous tick), then designs from the
    current model (:func:`design`, rise time 0.2 s on yaw) and sets the next identification signal value
    (:class:`StepSignal`, zero until the filters hold their first sample).

    Raises
    ------
    rotorlab.errors.DataError
        No convergence within the module's 20 s: PX4 aborts the whole autotune.
    """
    dt_us = int(round(loop_dt_s * 1e6))
    mdt = model_dt(gyro_cutoff_hz, loop_dt_s)
    scaler = max(int(round(mdt / loop_dt_s)), 1)
    sysid = SystemIdentification(loop_dt_s, gyro_cutoff_hz, mdt)
    signal = StepSignal(amplitude)
    if not RISE_TIME_RANGE_S[0] <= rise_time_s <= RISE_TIME_RANGE_S[1]:
        raise ValueError(f"MC_AT_RISE_TIME must be within {RISE_TIME_RANGE_S[0]:g}-{RISE_TIME_RANGE_S[1]:g} s "
                         f"(mc_autotune_attitude_control_params.c), got {rise_time_s:g}")
    rise = YAW_RISE_TIME_S if axis == "yaw" else rise_time_s
    # the state starts on a publishing tick: the model is reset, the gains designed from it, no signal yet
    kid = (math.nan,) * 4
    rate_sp, last_pub_us, counter, k = 0.0, 0, 0, 0
    while True:
        k += 1
        now_us = k * dt_us
        u, y = loop(rate_sp)
        sysid.update_filters(input_scale * u, y)
        counter += 1
        if counter >= scaler:
            sysid.update()
            counter = 0
        if now_us - last_pub_us <= PUBLISH_S * 1e6:
            continue
        if np.all(sysid.variances < CONVERGED_VARIANCE) and now_us > MIN_AXIS_S * 1e6:
            num, den = _model(sysid, input_scale)
            return AxisResult(axis, num, den, mdt, *kid, now_us * 1e-6)
        if now_us > TIMEOUT_S * 1e6:
            raise DataError(f"PX4 autotune: the {axis} model did not converge within {TIMEOUT_S:g} s "
                            f"(coefficient variances {np.array2string(sysid.variances, precision=3)}); "
                            "PX4 aborts the autotune and keeps the flown gains")
        kid = design(*_model(sysid, input_scale), mdt, rise)
        rate_sp = signal.next() if sysid.initialised else 0.0
        last_pub_us = now_us


def _model(sysid, input_scale):
    a1, a2, b0, b1, b2 = sysid.theta
    return np.array([b0, b1, b2]) * input_scale, np.array([1.0, a1, a2])


def check_gains(results: Mapping[str, AxisResult]) -> None:
    """PX4's ``areGainsGood`` on the set of axes: ``0 < kc < 0.5``, ``0 < ki < 10``, ``0 <= kd < 0.1`` and
    ``0 < att_p < 12`` on every axis (standard form). PX4 applies all axes or none.

    Raises
    ------
    rotorlab.errors.DataError
        Naming every axis and gain outside its bound.
    """
    bad = []
    for axis, r in results.items():
        for what, v, ok in (("kc", r.kc, 0 < r.kc < 0.5), ("ki", r.ki, 0 < r.ki < 10),
                            ("kd", r.kd, 0 <= r.kd < 0.1), ("attitude P", r.att_p, 0 < r.att_p < 12)):
            if not ok:
                bad.append(f"{axis} {what} = {v:.4g}")
    if bad:
        raise DataError("PX4 autotune would reject the gains and keep the flown ones on every axis: "
                        + ", ".join(bad) + " (accepted: kc 0-0.5, ki 0-10, kd 0-0.1, attitude P 0-12)")


def autotune_params(results: Mapping[str, AxisResult]) -> dict[str, float]:
    """The parameters the module saves for ``results`` after :func:`check_gains`: the parallel form
    ``MC_*RATE_P = kc``, ``MC_*RATE_K = 1``, ``MC_*RATE_I = kc ki``, ``MC_*RATE_D = kc kd``, ``MC_*_P = att_p``
    (``saveGainsToParams``). PX4 writes them without its parameters' documented ranges (``MC_ROLLRATE_D``'s
    0.01, for instance, is a ground-station bound, not a firmware clamp).

    Raises
    ------
    rotorlab.errors.DataError
        When :func:`check_gains` rejects the set.
    """
    check_gains(results)
    out = {}
    for axis, r in results.items():
        n = px4.axis_names(axis)
        out.update({n["P"]: r.kc, n["K"]: 1.0, n["I"]: r.kc * r.ki, n["D"]: r.kc * r.kd, n["ANG_P"]: r.att_p})
    return out


def autotune_gains(models: Mapping[str, tuple], model_dt_s: float,
                   rise_time_s: float = RISE_TIME_DEFAULT_S) -> dict[str, float]:
    """The parameters the module saves for given ARX ``models`` (axis -> ``(num, den)`` at ``model_dt_s``):
    :func:`design` per axis (yaw at 0.2 s), then :func:`autotune_params`.

    Raises
    ------
    rotorlab.errors.DataError
        When PX4's check rejects the set (it then keeps the flown gains on every axis).

    Examples
    --------
    >>> g = autotune_gains({"roll": ((0.0098, -0.162, 0.147), (1.0, -1.814, 0.822))}, 0.004)
    >>> sorted(g)
    ['MC_ROLLRATE_D', 'MC_ROLLRATE_I', 'MC_ROLLRATE_K', 'MC_ROLLRATE_P', 'MC_ROLL_P']
    """
    res = {}
    for axis, (num, den) in models.items():
        rise = YAW_RISE_TIME_S if axis == "yaw" else rise_time_s
        res[axis] = AxisResult(axis, np.asarray(num, float), np.asarray(den, float), model_dt_s,
                               *design(num, den, model_dt_s, rise), math.nan)
    return autotune_params(res)
