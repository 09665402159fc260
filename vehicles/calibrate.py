"""Calibrate a variable-pitch twin's pitch rig to its published identified model.

The physical structure (rigid airframe + rotor damping + elastic rig/airframe mount with its own damping on a
light ring with a damped bearing) reproduces ``K (s + z) / (s^2 + a s + b)`` exactly when the ring is
massless and the servo is instantaneous (see the vehicle READMEs for the closed form). The real twin has a
ring inertia, a servo lag, rotor H-force damping and the elastic IMU mount, so the four free parameters
(thrust slope, mount stiffness and damping, bearing damping) are refined by least squares on the twin's own
linearisation (``rotorlab.sim.linearize``) over 1-15 rad/s. The airframe inertia, rotor and IMU numbers stay
as designed.

Run ``python -m rotorlab.vehicles.calibrate anteos-p2a2`` and copy the printed values into the TOML.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import scipy.optimize as so

W_FIT_RAD_S = np.logspace(0.0, np.log10(15.0), 24)


def _with(v, slope, k, c, db, axis="pitch"):
    rig = dataclasses.replace(v.rigs[axis], mount_stiffness_Nm_per_rad=k, mount_damping_Nms_per_rad=c,
                              bearing_damping_Nms_per_rad=db)
    rotor = dataclasses.replace(v.rotor, thrust_slope_N_per_rad=slope)
    return dataclasses.replace(v, rotor=rotor, rigs={**v.rigs, axis: rig})


def closed_form(v, axis="pitch"):
    """Massless-ring, instantaneous-servo solution: (thrust slope, k, c, d_b) from the published model."""
    pm = v.published["testbed"]
    K = pm.num[0]
    z = pm.num[1] / pm.num[0]
    a, b = pm.den[1] / pm.den[0], pm.den[2] / pm.den[0]
    J = v.inertia_kgm2[1 if axis == "pitch" else 0]
    l = v.arm_m
    d_a = 2 * l**2 * v.rotor.axial_damping_N_per_mps
    d_sum = b * J / z  # d_a + d_b
    d_b = d_sum - d_a
    D = d_b**2 / (d_sum - (a - z) * J)  # d_b + c
    c = D - d_b
    k = z * D
    M_u = K * np.pi / 180.0 * J  # N m per %
    slope = M_u / (l * v.rotor.blade_pitch_per_pct_rad)
    return slope, k, c, d_b


def calibrate(vehicle: str, axis: str = "pitch"):
    from rotorlab import lti
    from rotorlab.sim.linearize import linearize
    from rotorlab.vehicles import load_vehicle

    import control as ct

    v = load_vehicle(vehicle)
    pm = v.published["testbed"]
    target = lti.freqresp(ct.tf(pm.num, pm.den), W_FIT_RAD_S)[:, 0, 0]
    x0 = np.log(closed_form(v, axis))

    def resid(x):
        vv = _with(v, *np.exp(x), axis=axis)
        G = linearize(f"{axis}-rig", vv, axis, f"gyro_{axis}", delay=False)
        r = np.log(lti.freqresp(G, W_FIT_RAD_S)[:, 0, 0] / target)
        return np.concatenate([r.real, r.imag])

    sol = so.least_squares(resid, x0, x_scale=1.0, diff_step=1e-4)
    slope, k, c, db = np.exp(sol.x)
    r = resid(sol.x)
    n = len(W_FIT_RAD_S)
    err_db = 20 / np.log(10) * np.max(np.abs(r[:n]))
    err_deg = np.degrees(np.max(np.abs(r[n:])))
    return dict(thrust_slope_N_per_rad=slope, mount_stiffness_Nm_per_rad=k, mount_damping_Nms_per_rad=c,
                bearing_damping_Nms_per_rad=db, max_error_db=err_db, max_error_deg=err_deg)


if __name__ == "__main__":
    for name, val in calibrate(*sys.argv[1:]).items():
        print(f"{name} = {val:.6g}")
