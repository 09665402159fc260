"""Closed-loop grey-box identification of the three attitude axes by ref. 002's protocol, on a twin.

Per axis: the ``prbs-periodic`` experiment (known hand-tuned PD, full-length PRBS on the set-point repeated
period after period; roll and pitch on their one-axis rigs, yaw in free flight), the logs averaged over the
periods after the first (:func:`rotorlab.ident.periodic_average`), and the indirect closed-loop output-error
fit of the TUHH axis structure (:func:`rotorlab.ident.oe_fit_closed_loop` with
:func:`rotorlab.ident.structures.tuhh_axis_structure`) on angle and rate, with 95 % intervals. The torque gain
``K`` is fixed a priori as TUHH did (from the vehicle file's rotor coefficients), so ``J``, ``p``, ``Td`` (and
the yaw zero ``z``) are estimated. Two references: :func:`physical`, the twin's own parameters (the inertia about
the axis from MuJoCo's mass matrix, rig ring and IMU board included; the rotors' motor pole, delay and yaw zero
from the vehicle file), and :func:`truth`, the structure's pseudo-true values for the twin (what the estimate
converges to without noise; the structure cannot hold the IMU mount, the speed map's curvature or the yaw drag),
which the 95 % intervals, taken from the spread between the averaged periods, are meant to cover.

This module sits in ``rotorlab/`` because it joins the simulator (``rotorlab.sim``) and ``rotorlab.ident``,
which never import each other.
"""

from __future__ import annotations

import math

import control as ct
import mujoco
import numpy as np

from rotorlab.ident import oe_fit_closed_loop, split_periods
from rotorlab.ident.structures import tuhh_axis_structure
from rotorlab.scenes import build_scene
from rotorlab.sim.disturbances.input_disturbance_step import axis_torque_per_pct
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.scenarios import prbs_periodic
from rotorlab.vehicles import load_vehicle

AXES = ("roll", "pitch", "yaw")
SCENE = {"roll": "roll-rig", "pitch": "pitch-rig", "yaw": "free-flight"}
#: [set-point, angle, rate] columns of each axis' log (the identification scenario's)
COLUMNS = {axis: prbs_periodic.AXES[axis][:3] for axis in AXES}
#: rotors that drive each axis (1-based; plus layout: pitch 1/3, roll 2/4, yaw all four)
ROTORS = {"roll": (2, 4), "pitch": (1, 3), "yaw": (1, 2, 3, 4)}
#: where the fit starts: away from the truth (and from ref. 002's table), so a converged fit means something
START = {"J": 0.01, "p": 15.0, "Td": 0.01, "z": 1.0}
#: ref. 002 table 1 (p and z as root magnitudes)
PUBLISHED = {"roll": {"J": 0.0181, "p": 27.106, "Td": 0.024}, "pitch": {"J": 0.0196, "p": 26.963, "Td": 0.028},
             "yaw": {"J": 0.0273, "p": 7.171, "z": 2.434, "Td": 0.016}}


def yaw_zero_rad_s(vehicle) -> float:
    """Yaw zero ``q / J_R`` of the rotor-inertia reaction (1/s): drag-torque slope over rotor inertia."""
    r = vehicle.rotor
    omega_h = float(r.speed(r.hover_command))
    q = 2.0 * r.torque_coefficient * 1.225 * math.pi * r.radius_m ** 5 * omega_h
    return q / r.inertia_kgm2 if r.inertia_kgm2 > 0 else math.inf


def apriori_gain(vehicle, axis: str) -> float:
    """The structure's fixed ``K`` in the twin's units (deg out, % in): roll/pitch moment per % times 180/pi;
    yaw ``2 (Q/T) dT/d% / z`` (the form ``K (s + z)``; 4 rotors take half the command each)."""
    per_pct = axis_torque_per_pct(vehicle)
    if axis == "yaw":
        dT = per_pct / vehicle.arm_m
        return 2.0 * vehicle.rotor.torque_to_thrust_m * dT / yaw_zero_rad_s(vehicle) * 180.0 / math.pi
    return per_pct * 180.0 / math.pi


def physical(vehicle, axis: str) -> dict:
    """The twin's own parameters: ``J`` (kg m^2, about the axis in its experiment's scene, from MuJoCo's mass
    matrix), ``p`` (1/s, the rotors' motor pole ``1/lag``), ``Td`` (s, the rotors' transport delay), yaw ``z``
    (``q / J_R``, 1/s)."""
    sc = build_scene(SCENE[axis], vehicle)
    m = sc.model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "hover"))
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    if axis == "yaw":
        dof = 5  # the free joint's rotation about body z
    else:
        dof = int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "rig_bearing")])
    r = vehicle.rotor
    idx = [i - 1 for i in ROTORS[axis]]
    out = {"J": float(M[dof, dof]), "p": float(np.mean([1.0 / r.lag_s[i] for i in idx])),
           "Td": float(np.mean([r.delay_s[i] for i in idx]))}
    if axis == "yaw":
        out["z"] = yaw_zero_rad_s(vehicle)
    return out


def truth(vehicle, axis: str, options: dict | None = None) -> dict:
    """The structure's true parameters for the twin in this experiment: its pseudo-true values (Ljung, *System
    Identification*, 2nd ed., sec. 8.3), the limit the estimate converges to as the noise vanishes.

    The TUHH structure (rigid ``J s^2``, one motor pole, one delay, a priori ``K``) cannot represent everything
    between the command and the IMU: the IMU's elastic mount (base-excited spring-damper ``(2 zeta w s + w^2) /
    (s^2 + 2 zeta w s + w^2)``: no lag at low frequency but a gain rising as ``1 + (w/w_m)^2``, which a faster
    ``p`` and, to keep the phase, a longer ``Td`` absorb), the curvature of the speed map over the experiment's
    command swings, the rotors' in-plane drag in yaw (a damping pole that moves the fitted yaw zero from
    ``q/J_R`` towards ``q/J_R - 4 k_h l^2/J``). So the structure's ``p``, ``Td`` (and ``J``, ``z``) are not the
    rotor's ``1/lag``, delay and ``q/J_R`` (:func:`physical`) but the structure's best account of the twin: the
    same experiment flown without sensor noise or gyro bias and fitted by the same criterion. The 95 %
    intervals are statements about this value; :func:`physical` is what the accuracy bounds compare with, and
    :func:`small_signal_truth` computes it independently from the twin's linearisation."""
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    key = (repr(v), axis, tuple(sorted((options or {}).items())))
    if key not in _TRUTH:
        ph = physical(v, axis)
        fit = _fit_experiment(v, axis, seed=0, periods=3, restarts=0, options=dict(options or {}), sensor_noise=False,
                              theta0=ph)
        if isinstance(fit, str):
            raise RuntimeError(f"the noise-free {axis} experiment that defines the truth stopped: {fit}")
        _TRUTH[key] = {**ph, **fit.params_free}
    return dict(_TRUTH[key])


#: noise-free fits are deterministic (no noise, no bias, no seed): one per vehicle spec, axis and options
_TRUTH: dict = {}


def small_signal_truth(vehicle, axis: str, options: dict | None = None) -> dict:
    """:func:`truth` from the twin's true linearisation instead of a flight: the structure fitted, by the same
    closed-loop criterion, to the exact periodic steady state of :func:`rotorlab.sim.linearize.linearize` (physics
    step, command held over the flight-software period, IMU sampled at the tick) under the experiment's PD and
    PRBS, computed at the PRBS period's harmonics. It leaves out the large-signal effects (speed-map curvature,
    the free-flight couplings) the flown experiment has."""
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    options = dict(options or {})
    dt = v.control_dt_s
    G = linearize(SCENE[axis], v, axis, [f"angle_{axis}", f"gyro_{axis}"], delay=True)
    A, B, C, D = (np.asarray(X, float) for X in (G.A, G.B, G.C, G.D))
    Ah, Bh = np.eye(A.shape[0]), np.zeros_like(B)
    for _ in range(int(round(dt / G.dt))):  # the command held over the physics steps of one tick
        Ah, Bh = A @ Ah, A @ Bh + B
    r, n = prbs_periodic.sequence(options, dt)
    kp, kd = prbs_periodic.pd_gains(axis, options)
    R = np.fft.rfft(r)
    Y = np.zeros((R.size, 2), dtype=complex)
    eye = np.eye(A.shape[0])
    for k in range(1, R.size):  # the mean (k = 0) is removed from data and model alike
        z = np.exp(2j * np.pi * k / n)
        Gz = C @ np.linalg.solve(z * eye - Ah, Bh) + D  # [angle, rate] per axis command (%)
        # u = kp (r - angle) - kd rate
        Y[k] = np.linalg.solve(np.eye(2) + Gz @ np.array([[kp, kd]]), Gz[:, 0] * kp * R[k])
    y = np.fft.irfft(Y, n=n, axis=0)
    ph = physical(v, axis)
    res = _fit_period(v, axis, kp, kd, r, y, dt, theta0=ph)
    return {**ph, **{k: float(res.params[k]) for k in res.free}}


def structure(vehicle, axis: str):
    """TUHH axis structure on ``[angle (deg), rate (deg/s)]`` from the axis command (%), ``K`` fixed a priori."""
    start = {k: v for k, v in START.items() if axis == "yaw" or k != "z"}
    return tuhh_axis_structure(axis, outputs=("angle", "rate"), K=apriori_gain(vehicle, axis), **start)


def _fit_period(v, axis: str, kp: float, kd: float, r, y, dt: float, **kw):
    """The indirect closed-loop fit of one period of the experiment's periodic steady state (``r`` the set-point,
    ``y`` [angle, rate]) through its PD (``kp`` %/deg, ``kd`` %/(deg/s)): the one fit the flown experiment and
    :func:`small_signal_truth` share. ``kw`` goes to :func:`rotorlab.ident.oe_fit_closed_loop`."""
    pd = prbs_periodic.pd_controller(axis, kp, kd, dt)
    # fixed signal weights on angle and rate, not the residual-based ML ones: with the structure's misfit those
    # would move the estimate's limit with the noise level, and the truth is the noise-free limit
    return oe_fit_closed_loop(structure(v, axis), ct.ss([], [], [], pd.D, dt), r, y, dt, feedback_output=(0, 1),
                              periods=2, reweight=False, **kw)


class _Fit:
    """One flown and fitted experiment (what :func:`identify_axis` and :func:`truth` share)."""
    def __init__(self, res, notes, n, dt):
        self.res, self.notes, self.n, self.dt = res, notes, n, dt
        self.params_free = {k: float(res.params[k]) for k in res.free}


def _fit_experiment(v, axis: str, seed: int, periods: int, restarts: int, options: dict, sensor_noise: bool = True,
                    theta0=None):
    dt = v.control_dt_s
    _, n = prbs_periodic.sequence(options, dt)
    run = run_scenario("prbs-periodic", v, scene=SCENE[axis], seed=seed, duration_s=periods * n * dt,
                       options=options, sensor_noise=sensor_noise)
    if run.stopped:
        return run.stopped
    notes = run.info["notes"]
    ref, ang, rate = COLUMNS[axis]
    data = np.column_stack([run.log[ref], run.log[ang], run.log[rate]])
    reps = split_periods(data, n, skip=1)
    avg = reps.mean(axis=0)
    kw = {}
    if sensor_noise:
        # the interval from the period-to-period spread (ref. 002's ten periods as replicates): honest for the
        # coloured closed-loop noise, blind to the structure's misfit, which :func:`truth` accounts for instead
        kw = {"cov": "periods", "replicates": reps[:, :, 1:]}
    res = _fit_period(v, axis, notes["kp"], notes["kd"], avg[:, 0], avg[:, 1:], dt, theta0=theta0, restarts=restarts,
                      rng=seed, **kw)
    return _Fit(res, notes, n, dt)


def identify_axis(vehicle, axis: str, seed: int = 0, periods: int = 11, restarts: int = 1,
                  options: dict | None = None) -> dict:
    """Run the experiment on ``axis`` and fit it. Returns ``params``, ``ci95`` (from the period-to-period
    spread), ``truth`` (:func:`truth`, the structure's pseudo-true values), ``physical`` (:func:`physical`),
    ``published``, ``std``, ``fit_vaf`` (angle, rate; on the averaged period), ``inside`` (truth inside the
    interval, per parameter), ``rel_error`` (to the truth), ``rel_error_physical`` and the experiment's
    settings."""
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    opts = dict(options or {})
    fit = _fit_experiment(v, axis, seed, periods, restarts, opts)
    if isinstance(fit, str):
        return {"stopped": fit}
    res, notes = fit.res, fit.notes
    tr, ph = truth(v, axis, opts), physical(v, axis)
    names = [k for k in ("J", "p", "Td", "z") if k in res.free]
    params = {k: float(res.params[k]) for k in names}
    ci = {k: [float(a) for a in res.ci95[k]] for k in names}
    return {"params": params, "ci95": ci, "truth": {k: tr[k] for k in names}, "physical": {k: ph[k] for k in names},
            "published": PUBLISHED[axis], "std": {k: float(res.std[k]) for k in names},
            "inside": {k: bool(ci[k][0] <= tr[k] <= ci[k][1]) for k in names},
            "rel_error": {k: params[k] / tr[k] - 1.0 for k in names},
            "rel_error_physical": {k: params[k] / ph[k] - 1.0 for k in names},
            "fit_vaf": [float(x) for x in res.fit_vaf], "at_bound": list(res.at_bound),
            "experiment": {"scene": SCENE[axis], "seed": seed, "periods_averaged": notes["periods"] - 1,
                           "period_s": fit.n * fit.dt, "dt_s": fit.dt, "pd": {"kp": notes["kp"], "kd": notes["kd"]},
                           "bit_s": notes["bit_s"], "amplitude_deg": notes["amplitude_deg"],
                           "interval": "period-to-period (Student t, periods - 1 dof)"}}


__all__ = ["AXES", "PUBLISHED", "identify_axis", "truth", "physical", "small_signal_truth", "structure", "apriori_gain",
           "yaw_zero_rad_s"]
