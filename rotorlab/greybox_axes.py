"""Closed-loop grey-box identification of the three attitude axes by ref. 002's protocol, on a twin.

Per axis: the ``prbs-periodic`` experiment (known hand-tuned PD, full-length PRBS on the set-point repeated
period after period; roll and pitch on their one-axis rigs, yaw in free flight), the logs averaged over the
periods after the first (:func:`rotorlab.ident.periodic_average`), and the indirect closed-loop output-error
fit of the TUHH axis structure (:func:`rotorlab.ident.oe_fit_closed_loop` with
:func:`rotorlab.ident.structures.tuhh_axis_structure`) on angle and rate, with 95 % intervals. The torque gain
``K`` is fixed a priori as TUHH did (from the vehicle file's rotor coefficients), so ``J``, ``p``, ``Td`` (and
the yaw zero ``z``) are estimated. The truth is the twin's own: the inertia about the axis from MuJoCo's mass
matrix (rig ring and IMU board included), the rotors' motor pole and delay from the vehicle file.

This module sits in ``rotorlab/`` because it joins the simulator (``rotorlab.sim``) and ``rotorlab.ident``,
which never import each other.
"""

from __future__ import annotations

import math

import control as ct
import mujoco
import numpy as np

from rotorlab.ident import oe_fit_closed_loop, periodic_average
from rotorlab.ident.structures import tuhh_axis_structure
from rotorlab.scenes import build_scene
from rotorlab.sim.disturbances.input_disturbance_step import axis_torque_per_pct
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.scenarios import prbs_periodic
from rotorlab.vehicles import load_vehicle

AXES = ("roll", "pitch", "yaw")
SCENE = {"roll": "roll-rig", "pitch": "pitch-rig", "yaw": "free-flight"}
COLUMNS = {"roll": ("phi_ref", "phi", "p"), "pitch": ("theta_ref", "theta", "q"), "yaw": ("psi_ref", "psi", "r")}
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


def truth(vehicle, axis: str) -> dict:
    """The twin's ``J`` (kg m^2, about the axis in its experiment's scene), ``p`` (1/s), ``Td`` (s), yaw ``z``."""
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


def structure(vehicle, axis: str):
    """TUHH axis structure on ``[angle (deg), rate (deg/s)]`` from the axis command (%), ``K`` fixed a priori."""
    start = {k: v for k, v in START.items() if axis == "yaw" or k != "z"}
    return tuhh_axis_structure(axis, outputs=("angle", "rate"), K=apriori_gain(vehicle, axis), **start)


def identify_axis(vehicle, axis: str, seed: int = 0, periods: int = 11, restarts: int = 1,
                  options: dict | None = None) -> dict:
    """Run the experiment on ``axis`` and fit it. Returns ``params``, ``ci95``, ``truth``, ``published``,
    ``std``, ``fit_vaf`` (angle, rate; on the averaged period), ``inside`` (truth inside the interval, per
    parameter), ``rel_error`` and the experiment's settings."""
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    dt = v.control_dt_s
    opts = dict(options or {})
    _, n = prbs_periodic.sequence(opts, dt)
    run = run_scenario("prbs-periodic", v, scene=SCENE[axis], seed=seed, duration_s=periods * n * dt, options=opts)
    if run.stopped:
        return {"stopped": run.stopped}
    notes = run.info["notes"]
    ref, ang, rate = COLUMNS[axis]
    data = np.column_stack([run.log[ref], run.log[ang], run.log[rate]])
    avg = periodic_average(data, n, skip=1)
    pd = prbs_periodic.pd_controller(axis, notes["kp"], notes["kd"], dt)
    K = ct.ss([], [], [], pd.D, dt)
    res = oe_fit_closed_loop(structure(v, axis), K, avg[:, 0], avg[:, 1:], dt, feedback_output=(0, 1),
                             periods=2, restarts=restarts, rng=seed)
    tr = truth(v, axis)
    names = [k for k in ("J", "p", "Td", "z") if k in res.free]
    params = {k: float(res.params[k]) for k in names}
    ci = {k: [float(a) for a in res.ci95[k]] for k in names}
    return {"params": params, "ci95": ci, "truth": tr, "published": PUBLISHED[axis],
            "std": {k: float(res.std[k]) for k in names},
            "inside": {k: bool(ci[k][0] <= tr[k] <= ci[k][1]) for k in names},
            "rel_error": {k: params[k] / tr[k] - 1.0 for k in names},
            "fit_vaf": [float(x) for x in res.fit_vaf], "at_bound": list(res.at_bound),
            "experiment": {"scene": SCENE[axis], "seed": seed, "periods_averaged": notes["periods"] - 1,
                           "period_s": n * dt, "dt_s": dt, "pd": {"kp": notes["kp"], "kd": notes["kd"]},
                           "bit_s": notes["bit_s"], "amplitude_deg": notes["amplitude_deg"]}}


__all__ = ["AXES", "PUBLISHED", "identify_axis", "truth", "structure", "apriori_gain", "yaw_zero_rad_s"]
