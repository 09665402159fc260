"""Hover derivatives of one rotor from blade-element/momentum theory and centre-spring flapping theory.

The formulas are the textbook hover results (Johnson, *Helicopter Theory*, ch. 2, 5 and 6; Padfield,
*Helicopter Flight Dynamics*, ch. 3; Prouty, *Helicopter Performance, Stability and Control*, ch. 1 and 9) for
an untwisted rotor in uniform inflow. The vehicle TOML carries the rotor data (radius, rotor speed, blades,
solidity, lift slope, profile drag, Lock number) and the derivatives the twin uses; ``tests/test_rotor_theory.py``
checks every derivative in a TOML against these formulas, and the vehicle READMEs print them with numbers.

Units: SI; ``mu`` is the advance ratio u / (Omega R); angles in rad. Everything here is per rotor.
"""

from __future__ import annotations

import dataclasses
import math

from .spec import G0, RHO_AIR, VehicleSpec


@dataclasses.dataclass(frozen=True)
class RotorHover:
    """Hover state and derivatives of one rotor (per rotor, SI)."""

    thrust_N: float
    omega_rad_s: float
    tip_speed_mps: float
    thrust_coefficient: float  # C_T = T / (rho A (Omega R)^2)
    inflow_ratio: float  # lambda_h = sqrt(C_T / 2)
    collective_rad: float  # theta_0 = 6 C_T / (sigma a) + 3 lambda / 2 (untwisted, uniform inflow)
    blade_flap_inertia_kgm2: float  # I_b = rho a c R^4 / gamma
    flap_frequency_ratio: float  # nu_beta = sqrt(1 + K_hub / ((N/2) I_b Omega^2))
    stiffness_number: float  # S_beta = 8 (nu_beta^2 - 1) / gamma
    dbeta_dmu: float  # longitudinal disc tilt per advance ratio, rad
    axial_damping_N_per_mps: float  # -dT/dw
    hforce_N_per_mps: float  # -dH/du
    hub_moment_Nm_per_mps: float  # dM_hub/du (hub spring times disc tilt)
    flap_arm_m: float  # hub moment / H-force
    disc_tilt_damping_Nms_per_rad: float  # aerodynamic damping of disc tilt, articulated-rotor value
    flap_lag_s: float  # 16 / (gamma Omega): quasi-steady lag of the disc behind the shaft


def hover(v: VehicleSpec) -> RotorHover:
    """Hover derivatives of one rotor of ``v`` from its ``[rotor]`` data.

    Formulas (per rotor):

    * ``C_T = T / (rho A (Omega R)^2)``, ``lambda = sqrt(C_T / 2)`` (momentum theory);
    * ``theta_0 = 6 C_T / (sigma a) + 3 lambda / 2`` from ``C_T = (sigma a / 2)(theta_0 / 3 - lambda / 2)``;
    * axial damping ``-dT/dw = rho A Omega R (sigma a / 8) / (1 + sigma a / (16 lambda))`` (BEMT with the
      inflow change, Johnson 2.x / Padfield 3.2);
    * disc tilt per advance ratio ``dbeta_1c/dmu = (8 theta_0 / 3 + 2 lambda) / (1 + S_beta^2)`` (Johnson 5.x,
      centre-spring rotor, quasi-steady flapping);
    * H-force ``-dH/du = (T dbeta_1c/dmu + rho A (Omega R)^2 sigma c_d0 / 4) / (Omega R)`` (thrust tilt plus
      blade profile drag);
    * hub moment ``dM/du = K_hub dbeta_1c/dmu / (Omega R)``, flap arm ``= (dM/du) / (-dH/du)``;
    * blade flap inertia ``I_b = rho a c R^4 / gamma`` with chord ``c = sigma pi R / N``; flap frequency ratio
      ``nu_beta^2 = 1 + K_hub / ((N/2) I_b Omega^2)``, stiffness number ``S_beta = 8 (nu_beta^2 - 1) / gamma``;
    * articulated disc-tilt damping ``(N/2)(gamma/8) I_b Omega = N rho a c R^4 Omega / 16`` and the quasi-steady
      flap lag ``16 / (gamma Omega)``.
    """
    r = v.rotor
    if r.solidity <= 0.0:
        raise ValueError(f"{v.name}: [rotor] has no blade-element data (solidity, lift slope, Lock number)")
    T = v.mass_kg * G0 / v.n_rotors
    omega = r.rotor_speed_rad_s if v.kind == "variable-pitch" else float(r.speed(r.hover_command))
    R = r.radius_m
    vt = omega * R
    A = math.pi * R**2
    q_tip = RHO_AIR * A * vt**2
    ct = T / q_tip
    lam = math.sqrt(ct / 2.0)
    sa = r.solidity * r.lift_slope_per_rad
    theta0 = 6.0 * ct / sa + 1.5 * lam
    chord = r.solidity * math.pi * R / r.blades
    i_b = RHO_AIR * r.lift_slope_per_rad * chord * R**4 / r.lock_number
    nu2 = 1.0 + r.hub_stiffness_Nm_per_rad / (r.blades / 2.0 * i_b * omega**2)
    s_beta = 8.0 * (nu2 - 1.0) / r.lock_number
    dbeta = (8.0 * theta0 / 3.0 + 2.0 * lam) / (1.0 + s_beta**2)
    kw = RHO_AIR * A * vt * (sa / 8.0) / (1.0 + sa / (16.0 * lam))
    kh = (T * dbeta + q_tip * r.solidity * r.profile_drag_coefficient / 4.0) / vt
    mu = r.hub_stiffness_Nm_per_rad * dbeta / vt
    return RotorHover(
        thrust_N=T, omega_rad_s=omega, tip_speed_mps=vt, thrust_coefficient=ct, inflow_ratio=lam,
        collective_rad=theta0, blade_flap_inertia_kgm2=i_b, flap_frequency_ratio=math.sqrt(nu2),
        stiffness_number=s_beta, dbeta_dmu=dbeta, axial_damping_N_per_mps=kw, hforce_N_per_mps=kh,
        hub_moment_Nm_per_mps=mu, flap_arm_m=mu / kh,
        disc_tilt_damping_Nms_per_rad=r.blades / 2.0 * r.lock_number / 8.0 * i_b * omega,
        flap_lag_s=16.0 / (r.lock_number * omega),
    )


def thrust_slope_N_per_rad(v: VehicleSpec) -> float:
    """BEMT collective-pitch thrust slope ``dT/dtheta = rho A (Omega R)^2 (sigma a / 6) / (1 + sigma a / (16 lambda))``."""
    h = hover(v)
    r = v.rotor
    sa = r.solidity * r.lift_slope_per_rad
    return RHO_AIR * math.pi * r.radius_m**2 * h.tip_speed_mps**2 * (sa / 6.0) / (1.0 + sa / (16.0 * h.inflow_ratio))
