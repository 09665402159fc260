"""PX4's multicopter autotune rule: the rate PID and attitude P that ``mc_autotune_attitude_control`` computes from
the 2-pole ARX model it identifies per axis, written from PX4's source as formulas (a baseline to compare tuned
gains against).

Sources (PX4-Autopilot main): src/lib/pid_design/pid_design.hpp (``computePidGmvc``: generalised minimum-variance
PID of Yamamoto, Fujii & Kaneda 1998, with PX4's extra division of the integral gain by 5);
src/modules/mc_autotune_attitude_control/mc_autotune_attitude_control.cpp (model sample time, design arguments,
attitude gain rule, gain checks, parallel-form parameters); mc_autotune_attitude_control_params.c (MC_AT_RISE_TIME,
0.01-0.5 s, default 0.14 s).

The model (PX4's ``ArxRls<2, 2, 1>``) is ``A(q^-1) y[k] = q^-1 B(q^-1) u[k]`` with ``A = 1 + a1 q^-1 + a2 q^-2``,
``B = b0 + b1 q^-1 + b2 q^-2``, ``u`` the normalised torque and ``y`` the rate (rad/s), at the model sample time
:func:`model_dt`. The rule, with ``rho = dt / sigma`` (``sigma`` the desired rise time), ``mu = 0.25 (1 - delta)
+ 0.51 delta`` (``delta`` the damping index) and ``lambda`` the detuning::

    p1 = -2 exp(-rho / (2 mu)) cos(sqrt(4 mu - 1) rho / (2 mu)),   p2 = exp(-rho / mu)
    e1 = -a1 + p1 + 1
    f0 = -a1 e1 + a1 - a2 + e1 + p2,   f1 = a1 e1 - a2 e1 + a2,   f2 = a2 e1
    nu = lambda + (e1 + 1)(b0 + b1 + b2)
    kc = -(f1 + 2 f2) / nu,   ki = -(f0 + f1 + f2) / (dt (f1 + 2 f2)) / 5,   kd = -dt f2 / (f1 + 2 f2)

The multicopter module calls it with ``sigma`` = MC_AT_RISE_TIME (0.2 s on yaw), ``delta = 0``, ``lambda = 0.7``,
sets a slightly negative ``kd`` (above -0.001) to 0, takes the attitude gain from "an error of 60 deg gives full
output", ``clip(1 / (60 deg x kc), 2, 6.5)``, refuses gains outside ``0 < kc < 0.5``, ``0 < ki < 10``,
``0 <= kd < 0.1``, ``0 < att_p < 12``, and saves the parallel form ``MC_*RATE_P = kc``, ``MC_*RATE_K = 1``,
``MC_*RATE_I = kc ki``, ``MC_*RATE_D = kc kd``, ``MC_*_P = att_p``.

PX4 identifies the model on-line by recursive least squares on band-passed torque and rate (the gyro low-pass and
a 0.5 Hz high-pass on both); :func:`arx221_fit` is the batch least-squares estimate the recursion converges to
without forgetting, on the signals given (filter them first to reproduce PX4's weighting).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from rotorlab.autopilots import px4
from rotorlab.errors import DataError

__all__ = ["gmvc_pid", "model_dt", "arx221_fit", "autotune_gains", "RISE_TIME_DEFAULT_S", "YAW_RISE_TIME_S"]

RISE_TIME_DEFAULT_S = 0.14  # MC_AT_RISE_TIME default
YAW_RISE_TIME_S = 0.2  # the module's fixed yaw rise time
_MODEL_DT_MIN_S, _MODEL_DT_MAX_S = 2e-3, 10e-3


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
    kc = -(f1 + 2.0 * f2) / nu
    ki = -(f0 + f1 + f2) / (dt_s * (f1 + 2.0 * f2)) / 5.0
    kd = -dt_s * f2 / (f1 + 2.0 * f2)
    return kc, ki, kd


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
    dt = min(max(max(1.0 / (2.0 * imu_gyro_cutoff_hz), loop_dt_s), _MODEL_DT_MIN_S), _MODEL_DT_MAX_S)
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


def autotune_gains(models: Mapping[str, tuple], model_dt_s: float,
                   rise_time_s: float = RISE_TIME_DEFAULT_S) -> dict[str, float]:
    """The PX4 parameters ``mc_autotune_attitude_control`` would save for the ARX ``models`` (axis ->
    ``(num, den)``, see :func:`arx221_fit`), rise time MC_AT_RISE_TIME (yaw: 0.2 s).

    Raises
    ------
    rotorlab.errors.DataError
        When PX4's own check would reject the gains (it then keeps the old ones): the axis and the gain named.

    Examples
    --------
    >>> g = autotune_gains({"roll": ((0.0098, -0.162, 0.147), (1.0, -1.814, 0.822))}, 0.004)
    >>> sorted(g)
    ['MC_ROLLRATE_D', 'MC_ROLLRATE_I', 'MC_ROLLRATE_K', 'MC_ROLLRATE_P', 'MC_ROLL_P']
    """
    out = {}
    for axis, (num, den) in models.items():
        rise = YAW_RISE_TIME_S if axis == "yaw" else rise_time_s
        kc, ki, kd = gmvc_pid(num, den, model_dt_s, rise, 0.0, 0.7)
        if -0.001 < kd < 0.0:
            kd = 0.0
        att_p = min(max(1.0 / (math.radians(60.0) * kc), 2.0), 6.5) if kc else math.inf
        for what, v, ok in (("kc", kc, 0 < kc < 0.5), ("ki", ki, 0 < ki < 10), ("kd", kd, 0 <= kd < 0.1),
                            ("attitude P", att_p, 0 < att_p < 12)):
            if not ok:
                raise DataError(f"PX4 autotune would reject the {axis} gains: {what} = {v:.4g} is outside its "
                                "accepted range (kc 0-0.5, ki 0-10, kd 0-0.1, attitude P 0-12)")
        n = px4.axis_names(axis)
        out.update({n["P"]: kc, n["K"]: 1.0, n["I"]: kc * ki, n["D"]: kc * kd, n["ANG_P"]: att_p})
    return out
