"""Calibrate a variable-pitch twin's rotors to its published test-bed model.

The rig is test equipment (a light ring on a greased bearing, the airframe clamped to it) and shapes nothing in
1-15 rad/s; the response belongs to the vehicle. Its pitch dynamics are a rigid airframe (inertia J, control
moment M_u u, thrust damping d_a = 2 l^2 (-dT/dw) of the fore/aft rotors) dragged by four rotor discs through
their hingeless hubs: each disc tilts against the hub spring (K, c) and the air damps its tilt rate (D). With
massless discs and an instantaneous servo the pitch rate is exactly the published structure,

    q/M = ((D + c) s + K) / (J (D + c) s^2 + (J K + d_a (D + c) + D c) s + (d_a + D) K)      (K, c, D: 4 rotors)

so ``closed_form`` solves (M_u, K, c, D) from K_pub (s + z) / (s^2 + a s + b). The twin has disc inertia, a
servo lag, the IMU mount and the ring, so ``calibrate`` refines the four by least squares on the twin's own
linearisation (``rotorlab.sim.linearize``) of the pitch rig over 1-15 rad/s. Airframe inertia, the thrust
damping and the speed derivatives come from rotor theory (``rotor_theory``) and stay fixed; the fitted hub
damping is held within the hingeless-rotor range ``HUB_DAMPING_RANGE_NMS`` (per rotor, scaled by R^5 Omega).

Run ``python -m rotorlab.vehicles.calibrate anteos-p2a2`` and copy the printed values into the TOML.
"""

from __future__ import annotations

import dataclasses
import sys

import control as ct
import numpy as np
import scipy.optimize as so

from rotorlab import lti
from rotorlab.sim.linearize import linearize
from rotorlab.vehicles import load_vehicle
from rotorlab.vehicles.rotor_theory import hover, thrust_slope_N_per_rad

W_FIT_RAD_S = np.logspace(0.0, np.log10(15.0), 24)
# hub damping per rotor for the P2-A2 rotor (R = 0.27 m, Omega = 316 rad/s), hingeless/centre-spring theory
# with Lock number 1-4 and flap frequency ratio 1-1.5 (issue #11's independent analysis; README)
HUB_DAMPING_RANGE_NMS = (0.06, 0.5)
P2A2_R5_OMEGA = 0.27**5 * 316.0


def hub_damping_range(v) -> tuple[float, float]:
    """Theory range of the hub damping per rotor, scaled from the P2-A2 by R^5 Omega (D ~ rho a c R^4 Omega)."""
    k = v.rotor.radius_m**5 * v.rotor.rotor_speed_rad_s / P2A2_R5_OMEGA
    return HUB_DAMPING_RANGE_NMS[0] * k, HUB_DAMPING_RANGE_NMS[1] * k


def with_rotor(v, **changes):
    """``v`` with rotor fields replaced."""
    return dataclasses.replace(v, rotor=dataclasses.replace(v.rotor, **changes))


def _with(v, slope, k, c, d):
    return with_rotor(v, thrust_slope_N_per_rad=slope, hub_stiffness_Nm_per_rad=k,
                      hub_spring_damping_Nms_per_rad=c, hub_damping_Nms_per_rad=d)


def closed_form(v, axis="pitch"):
    """Massless-disc, instantaneous-servo solution per rotor: (thrust slope, K_hub, c_hub, D_hub)."""
    pm = v.published["testbed"]
    K = pm.num[0]
    z = pm.num[1] / pm.num[0]
    a, b = pm.den[1] / pm.den[0], pm.den[2] / pm.den[0]
    J = v.inertia_kgm2[1 if axis == "pitch" else 0] + v.rigs[axis].ring_inertia_kgm2
    l = v.arm_m
    d_a = 2 * l**2 * v.rotor.axial_damping_N_per_mps
    d_sum = b * J / z  # d_a + D
    D = d_sum - d_a
    Dc = D**2 / (d_sum - (a - z) * J)  # D + c
    c = Dc - D
    k = z * Dc
    M_u = K * np.pi / 180.0 * J  # N m per %
    slope = M_u / (l * v.rotor.blade_pitch_per_pct_rad)
    n = v.n_rotors
    return slope, k / n, c / n, D / n


def calibrate(vehicle: str, axis: str = "pitch"):
    """Least-squares rotor calibration against the published test-bed model; returns the TOML values and fit."""
    v = load_vehicle(vehicle)
    pm = v.published["testbed"]
    target = lti.freqresp(ct.tf(pm.num, pm.den), W_FIT_RAD_S)[:, 0, 0]
    x0 = np.log(np.maximum(closed_form(v, axis), 1e-6))
    lo, hi = np.full(4, -np.inf), np.full(4, np.inf)
    lo[3], hi[3] = np.log(hub_damping_range(v))
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)

    def resid(x):
        vv = _with(v, *np.exp(x))
        G = linearize(f"{axis}-rig", vv, axis, f"gyro_{axis}", delay=False)
        r = np.log(lti.freqresp(G, W_FIT_RAD_S)[:, 0, 0] / target)
        return np.concatenate([r.real, r.imag])

    sol = so.least_squares(resid, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4)
    slope, k, c, d = np.exp(sol.x)
    r = resid(sol.x)
    n = len(W_FIT_RAD_S)
    h = hover(_with(v, slope, k, c, d))
    return dict(thrust_slope_N_per_rad=slope, hub_stiffness_Nm_per_rad=k, hub_spring_damping_Nms_per_rad=c,
                hub_damping_Nms_per_rad=d, max_error_db=20 / np.log(10) * np.max(np.abs(r[:n])),
                max_error_deg=np.degrees(np.max(np.abs(r[n:]))),
                # theory derivatives at the calibrated hub (copy axial damping, H-force and flap arm too)
                axial_damping_N_per_mps=h.axial_damping_N_per_mps, hforce_N_per_mps=h.hforce_N_per_mps,
                flap_arm_m=h.flap_arm_m, flap_frequency_ratio=h.flap_frequency_ratio,
                hub_lag_s=(d + c) / k, flap_lag_theory_s=h.flap_lag_s,
                thrust_slope_bemt_N_per_rad=thrust_slope_N_per_rad(v))


if __name__ == "__main__":
    for name, val in calibrate(*sys.argv[1:]).items():
        print(f"{name} = {val:.6g}")
