"""A generic multirotor twin from a few physical numbers: the vehicle TOML that ``rotorlab vehicle new`` writes.

Everything not given is estimated, and the file says how, one comment per number:

* propeller (radius ``R`` = half the diameter): thrust ``T = C_T rho pi R^4 Omega^2`` and drag torque ``Q = C_Q rho
  pi R^5 Omega^2`` (rotorlab's convention, ``RotorSpec``). Without thrust-stand numbers, ``C_T = 4 c_T / pi^3`` and
  ``C_Q = 4 c_P / pi^4`` from the static coefficients of the UIUC propeller database convention ``T = c_T rho n^2
  D^4``, ``P = c_P rho n^3 D^5`` (n in rev/s, D = 2R), with the typical two-blade values :data:`STATIC_CT` and
  :data:`STATIC_CP` (Brandt and Selig, "Propeller Performance Data at Low Reynolds Numbers", AIAA 2011-1255);
* maximum rotor speed: given, or ``Omega_max = eta kv (2 pi / 60) cells V_cell`` (loaded-speed fraction
  :data:`LOADED_SPEED_FRACTION`, nominal :data:`CELL_VOLTAGE_V` per LiPo cell), or, with neither, the speed that
  gives the thrust-to-weight ratio :data:`DEFAULT_THRUST_TO_WEIGHT`; the ESC maps the command ``b`` in [0, 1]
  linearly to speed, ``Omega(b) = Omega_max b``, and the hover command is ``b_H = sqrt(m g / (n k_T)) / Omega_max``;
* inertia: given, or a central box (the mass not in the rotor groups; half sizes ``body_size_m``) plus the rotor
  groups (motor, propeller, ESC, arm tip: :data:`ROTOR_MASS_FRACTION` of the mass) as point masses at the hubs,
  ``I_xx = m_c (b_y^2 + b_z^2) / 3 + sum m_r (y_i^2 + h^2)`` and alike (the central-body-plus-point-motors model of
  Beard, "Quadrotor Dynamics and Control", BYU 2008, sec. 3, with a box for the body), about the CG;
* motor time constant and transport delay: given, or the defaults :data:`DEFAULT_MOTOR_TAU_S` and
  :data:`DEFAULT_DELAY_S` (to be replaced by a thrust-stand step or a flight log's identification).

The written file is read back with :func:`rotorlab.vehicles.spec.parse_vehicle` before it is saved, so it loads
and its hover command holds its weight; impossible numbers are refused with the field and the physical rule.

Examples
--------
>>> from rotorlab.vehicles.generic import new_vehicle_toml
>>> text = new_vehicle_toml("my-quad", frame="quad-x", mass_kg=1.2, arm_m=0.18, prop_in=9.0)
>>> "frame = \\"quad-x\\"" in text
True
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from rotorlab import atomic
from rotorlab.errors import ConfigError
from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.ident.rotor import fit_speed_map, fit_thrust_coefficient, fit_torque_coefficient

from .spec import FRAMES, G0, RHO_AIR, VehicleSpec, parse_vehicle

STATIC_CT = 0.11  # UIUC static thrust coefficient, 9-11 inch two-blade propellers (0.09-0.13)
STATIC_CP = 0.045  # UIUC static power coefficient, same propellers (0.035-0.06)
CELL_VOLTAGE_V = 3.7  # nominal LiPo cell
LOADED_SPEED_FRACTION = 0.8  # a loaded propeller turns at about 80 % of its motor's no-load speed kv V
DEFAULT_THRUST_TO_WEIGHT = 2.0  # common multirotor design point when nothing about the motors is known
ROTOR_MASS_FRACTION = 0.3  # motors, propellers, ESCs and arm tips: about 30 % of a small multirotor's mass
DEFAULT_MOTOR_TAU_S = 0.03  # 9-13 inch propellers: 12-37 ms (PX4 x500 model 12.5/25 ms, TUHH quad 37 ms)
DEFAULT_DELAY_S = 0.01  # gyro filtering, ESC protocol and update: about 10 ms on a typical flight stack
PHYSICS_DT_S = 0.001  # the scenes' physics step: delays are whole steps of it, the flight-software period too
INCH_M = 0.0254


def _positive(field: str, value, what: str) -> float:
    if value is None or not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ConfigError(what, field=field, expected="a finite number > 0", got=value)
    return float(value)


def _fmt(x: float) -> str:
    return repr(float(x))


def new_vehicle_toml(name: str, *, frame: str, mass_kg: float, arm_m: float, prop_in: float,
                     kv: float | None = None, cells: int | None = None, max_speed_rad_s: float | None = None,
                     thrust_coefficient: float | None = None, torque_coefficient: float | None = None,
                     motor_tau_s: float | None = None, delay_s: float | None = None,
                     inertia_kgm2=None, rotor_inertia_kgm2: float = 0.0, rate_hz: float = 250.0,
                     thrust_stand: dict | None = None, src="<vehicle new>") -> str:
    """The vehicle TOML text of a generic variable-RPM multirotor, every estimated number with its formula.

    Parameters
    ----------
    name : str
        Vehicle name (``[vehicle] name``).
    frame : {'quad-plus', 'quad-x', 'hexa-x'}
        Rotor layout and numbering (:data:`rotorlab.vehicles.spec.FRAMES`).
    mass_kg, arm_m, prop_in : float
        Take-off mass (kg), CG-to-hub distance (m), propeller diameter (inch).
    kv, cells : float, int, optional
        Motor velocity constant (rpm/V) and LiPo cell count, for the maximum speed.
    max_speed_rad_s : float, optional
        Maximum rotor speed (rad/s); overrides kv/cells.
    thrust_coefficient, torque_coefficient : float, optional
        Thrust-stand ``C_T``, ``C_Q`` in rotorlab's convention (see the module docstring).
    motor_tau_s, delay_s : float, optional
        Motor time constant and transport delay, s (the delay is rounded to the 1 ms physics step).
    inertia_kgm2 : sequence of 3 floats, optional
        Principal moments about the CG, kg m^2.
    rotor_inertia_kgm2 : float
        Propeller + motor bell about the spin axis (0: the spin-up yaw reaction is left out).
    rate_hz : float
        Flight-software rate; its period must be a whole number of 1 ms physics steps.
    thrust_stand : dict, optional
        A thrust-stand sweep ``{"command": b in [0, 1], "speed_rad_s", "thrust_N"[, "torque_Nm"], "source": name}``
        (arrays): ``C_T``, ``C_Q`` and the power-law speed map ``Omega(b) = a0 b^a1 + a2`` are fitted to it
        (``rotorlab.ident.rotor``) in place of the estimates; excludes the other motor and propeller numbers.

    Returns
    -------
    str
        TOML text that :func:`rotorlab.vehicles.spec.parse_vehicle` accepts.

    Raises
    ------
    ConfigError
        A number that is not positive and finite, an unknown frame, rotors that cannot lift the mass.
    """
    if frame not in FRAMES:
        raise ConfigError("unknown frame", field="frame", expected=f"one of {sorted(FRAMES)}", got=frame)
    n = len(FRAMES[frame][1])
    m = _positive("mass_kg", mass_kg, "the take-off mass")
    arm = _positive("arm_m", arm_m, "the CG-to-hub distance")
    R = _positive("prop_in", prop_in, "the propeller diameter") * INCH_M / 2.0
    if 2.0 * R * math.sin(math.pi / n) > 2.0 * arm:
        # neighbouring hubs are 2 arm sin(pi/n) apart: larger propellers would overlap
        raise ConfigError("neighbouring propellers overlap: the diameter must not exceed 2 arm sin(pi/n)",
                          field="prop_in", expected=f"<= {2 * arm * math.sin(math.pi / n) / INCH_M:.3g} inch",
                          got=prop_in)
    weight = m * G0
    if thrust_stand is not None:
        given = [k for k, x in (("kv", kv), ("cells", cells), ("max_speed_rad_s", max_speed_rad_s),
                                ("thrust_coefficient", thrust_coefficient),
                                ("torque_coefficient", torque_coefficient)) if x is not None]
        if given:
            raise ConfigError("the thrust stand gives the motor and propeller numbers", field=given[0],
                              expected="either a thrust-stand table or these numbers", got="both")
        ct, cq, (a0, a1, a2), lines_rotor, w_note = _thrust_stand(thrust_stand, R)
        w_field = "thrust_stand"
        k_thrust = ct * RHO_AIR * math.pi * R**4
        w_max = a0 + a2
    else:
        lines_rotor = []
        if thrust_coefficient is None:
            ct = 4.0 * STATIC_CT / math.pi**3
            lines_rotor.append(f"thrust_coefficient = {_fmt(ct)}  # 4 c_T / pi^3, UIUC static c_T = {STATIC_CT} "
                               "(estimate)")
        else:
            ct = _positive("thrust_coefficient", thrust_coefficient, "the thrust coefficient C_T")
            lines_rotor.append(f"thrust_coefficient = {_fmt(ct)}  # given (thrust stand)")
        if torque_coefficient is None:
            cq = 4.0 * STATIC_CP / math.pi**4
            lines_rotor.append(f"torque_coefficient = {_fmt(cq)}  # 4 c_P / pi^4, UIUC static c_P = {STATIC_CP} "
                               "(estimate)")
        else:
            cq = _positive("torque_coefficient", torque_coefficient, "the torque coefficient C_Q")
            lines_rotor.append(f"torque_coefficient = {_fmt(cq)}  # given (thrust stand)")
        k_thrust = ct * RHO_AIR * math.pi * R**4
        if max_speed_rad_s is not None:
            w_max = _positive("max_speed_rad_s", max_speed_rad_s, "the maximum rotor speed")
            w_note, w_field = "Omega_max given", "max_speed_rad_s"
        elif kv is not None or cells is not None:
            kv_ = _positive("kv", kv, "the motor velocity constant (rpm/V), given with cells")
            if not isinstance(cells, int) or isinstance(cells, bool) or cells < 1:
                raise ConfigError("the LiPo cell count, given with kv", field="cells",
                                  expected="a whole number >= 1", got=cells)
            w_max = LOADED_SPEED_FRACTION * kv_ * 2.0 * math.pi / 60.0 * cells * CELL_VOLTAGE_V
            w_note = (f"Omega_max = {LOADED_SPEED_FRACTION} kv 2 pi/60 cells {CELL_VOLTAGE_V} V = "
                      f"{LOADED_SPEED_FRACTION} x {kv_:g} x 2 pi/60 x {cells} x {CELL_VOLTAGE_V} (estimate)")
            w_field = "kv"
        else:
            w_max = math.sqrt(DEFAULT_THRUST_TO_WEIGHT * weight / (n * k_thrust))
            w_note = (f"Omega_max = sqrt({DEFAULT_THRUST_TO_WEIGHT} m g / (n k_T)): thrust-to-weight "
                      f"{DEFAULT_THRUST_TO_WEIGHT} (estimate)")
            w_field = "max_speed_rad_s"
        a0, a1, a2 = w_max, 1.0, 0.0
        w_note = f"Omega(b) = Omega_max b rad/s (linear ESC), {w_note}"
    t_max = n * k_thrust * w_max**2
    if t_max <= weight:
        raise ConfigError("the rotors cannot lift the vehicle: n k_T Omega_max^2 must exceed m g", field=w_field,
                          expected=f"thrust at full speed > weight {weight:.4g} N",
                          got=f"{t_max:.4g} N at Omega_max {w_max:.4g} rad/s")
    w_hover = math.sqrt(weight / (n * k_thrust))
    if w_hover <= a2:
        raise ConfigError("the motors idle faster than hover: Omega(0) = a2 must be below the hover speed",
                          field=w_field, expected=f"a2 < {w_hover:.4g} rad/s", got=a2)
    b_hover = ((w_hover - a2) / a0) ** (1.0 / a1)
    tau = DEFAULT_MOTOR_TAU_S if motor_tau_s is None else _positive("motor_tau_s", motor_tau_s,
                                                                     "the motor time constant")
    if delay_s is None:
        delay, delay_note = DEFAULT_DELAY_S, "flight stack and ESC (estimate)"
    else:
        if not (isinstance(delay_s, (int, float)) and math.isfinite(delay_s) and delay_s >= 0):
            raise ConfigError("the transport delay", field="delay_s", expected="a finite number >= 0", got=delay_s)
        delay, delay_note = round(delay_s / PHYSICS_DT_S) * PHYSICS_DT_S, "given, in whole 1 ms physics steps"
    period_steps = 1.0 / (_positive("rate_hz", rate_hz, "the flight-software rate") * PHYSICS_DT_S)
    if abs(period_steps - round(period_steps)) > 1e-9 or round(period_steps) < 1:
        raise ConfigError("the flight-software period must be a whole number of 1 ms physics steps",
                          field="rate_hz", expected="1000 / k Hz (1000, 500, 250, 200, ...)", got=rate_hz)

    body = (0.25 * arm, 0.25 * arm, 0.1 * arm)
    h = 0.1 * arm
    dirs = FRAMES[frame][0]
    if inertia_kgm2 is None:
        m_r = ROTOR_MASS_FRACTION * m / n
        m_c = m - n * m_r
        bx, by, bz = body
        ixx = m_c * (by**2 + bz**2) / 3.0 + sum(m_r * ((arm * y) ** 2 + h**2) for _, y in dirs)
        iyy = m_c * (bx**2 + bz**2) / 3.0 + sum(m_r * ((arm * x) ** 2 + h**2) for x, _ in dirs)
        izz = m_c * (bx**2 + by**2) / 3.0 + sum(m_r * arm**2 for _ in dirs)
        inertia = (ixx, iyy, izz)
        inertia_note = (f"box {m_c:.4g} kg (half sizes body_size_m) + {n} rotor groups of {m_r:.4g} kg "
                        f"({ROTOR_MASS_FRACTION} m / n) at the hubs: I_xx = m_c (b_y^2 + b_z^2)/3 + sum m_r (y_i^2 + h^2),"
                        f" I_zz = m_c (b_x^2 + b_y^2)/3 + n m_r arm^2 (estimate)")
    else:
        inertia = tuple(float(x) for x in inertia_kgm2)
        if len(inertia) != 3:
            raise ConfigError("the principal moments of inertia", field="inertia_kgm2",
                              expected="three numbers (I_xx, I_yy, I_zz)", got=list(inertia_kgm2))
        for x in inertia:
            _positive("inertia_kgm2", x, "a principal moment of inertia")
        inertia_note = "given"
    lim = math.floor(100.0 * min(b_hover, 1.0 - b_hover))
    if lim < 1:
        raise ConfigError("no control authority is left at hover: the hover command must be inside (0, 1)",
                          field=w_field, expected="b_H = Omega_H / Omega_max below 0.99",
                          got=f"b_H = {b_hover:.4f}")
    text = f"""# Generic {frame} multirotor written by `rotorlab vehicle new` (rotorlab.vehicles.generic): every estimated
# number says how it was estimated; replace estimates by measurements (thrust stand, pendulum, flight log) and
# keep the comments honest. n = {n} rotors, rho = {RHO_AIR} kg/m^3, g = {G0} m/s^2.

[vehicle]
name = "{name}"
description = "generic {frame}, {m:g} kg, arm {arm:g} m, {prop_in:g} inch propellers"
kind = "variable-rpm"

[airframe]
frame = "{frame}"
mass_kg = {_fmt(m)}  # given
inertia_kgm2 = [{', '.join(_fmt(x) for x in inertia)}]  # {inertia_note}
arm_m = {_fmt(arm)}  # given
rotor_height_m = {_fmt(h)}  # h = 0.1 arm: hubs above the CG (estimate)
body_size_m = [{', '.join(_fmt(x) for x in body)}]  # central box half sizes 0.25 arm, 0.25 arm, 0.1 arm (estimate)

[rotor]
radius_m = {_fmt(R)}  # half the {prop_in:g} inch diameter
torque_to_thrust_m = {_fmt(R * cq / ct)}  # Q/T = R C_Q / C_T
axial_damping_N_per_mps = 0.0  # not estimated
hforce_N_per_mps = 0.0  # rotor in-plane drag, not estimated
flap_arm_m = 0.0  # rigid propellers: no hub moment
lag_s = {_fmt(tau)}  # motor time constant, {"given" if motor_tau_s is not None else "typical (estimate)"}
delay_s = {_fmt(delay)}  # transport delay, {delay_note}
{chr(10).join(lines_rotor)}
speed_map = [{_fmt(a0)}, {_fmt(a1)}, {_fmt(a2)}]  # {w_note}
# k_T = C_T rho pi R^4 = {k_thrust:.6g} N/(rad/s)^2, hover speed Omega_H = sqrt(m g / (n k_T)) = {w_hover:.6g} rad/s
hover_command = {_fmt(b_hover)}  # b_H = ((Omega_H - a2) / a0)^(1/a1)
inertia_kgm2 = {_fmt(rotor_inertia_kgm2)}  # propeller + motor bell about the spin axis{"" if rotor_inertia_kgm2 else " (0: not modelled)"}

[flight_software]
rate_hz = {_fmt(rate_hz)}

[commands]
limit_pct = {lim:.1f}  # 100 min(b_H, 1 - b_H): every rotor stays in [0, 1] with roll and pitch saturated
rate_limit_dps = 220.0  # PX4's MC_ROLLRATE_MAX default
yaw_limit_pct = {lim:.1f}  # as limit_pct
yaw_rate_limit_dps = 200.0  # PX4's MC_YAWRATE_MAX default

[imu]  # a typical MEMS IMU, near-rigidly mounted at the CG (estimates)
mass_kg = 0.01
size_m = 0.02
offset_m = [0.0, 0.0, 0.0]
mount_frequency_hz = 100.0
mount_damping_ratio = 0.7
gyro_noise_dps = 0.1
gyro_bias_dps = 0.1
angle_noise_deg = 0.05
accel_noise_mps2 = 0.05
"""
    parse_vehicle(tomllib.loads(text), src, PHYSICS_DT_S)  # the file loads, hovers at b_H and can climb
    return text


def _thrust_stand(table: dict, radius_m: float):
    """(C_T, C_Q, speed map, TOML lines, speed-map note) fitted to a thrust-stand sweep (rotorlab.ident.rotor)."""
    src = table.get("source", "thrust stand")
    try:
        b, w, T = (np.asarray(table[k], dtype=float) for k in ("command", "speed_rad_s", "thrust_N"))
    except KeyError as exc:
        raise ConfigError("a thrust-stand table needs command, speed_rad_s and thrust_N columns", file=src,
                          field=str(exc.args[0]), expected="a column of that name") from None
    if np.any((b < 0) | (b > 1)):
        raise ConfigError("the ESC command of a thrust-stand table is a fraction of full command", file=src,
                          field="command", expected="values in [0, 1]", got=float(b[(b < 0) | (b > 1)][0]))
    ok = b > 0  # the power law has no value at b = 0
    thrust = fit_thrust_coefficient(w, T, RHO_AIR, radius_m)
    speed = fit_speed_map(b[ok], w[ok], "power")
    lines = [f"thrust_coefficient = {_fmt(thrust.coefficient)}  # {src}: T = K_T Omega^2, K_T = {thrust.K:.6g} "
             f"N/(rad/s)^2 (R^2 {thrust.r2:.4f}), C_T = K_T / (rho pi R^4)"]
    if "torque_Nm" in table:
        torque = fit_torque_coefficient(w, np.asarray(table["torque_Nm"], dtype=float), rho=RHO_AIR,
                                        radius_m=radius_m)
        cq = torque.coefficient
        lines.append(f"torque_coefficient = {_fmt(cq)}  # {src}: Q = K_Q Omega^2, K_Q = {torque.K:.6g} N m/(rad/s)^2, "
                     "C_Q = K_Q / (rho pi R^5)")
    else:
        cq = 4.0 * STATIC_CP / math.pi**4
        lines.append(f"torque_coefficient = {_fmt(cq)}  # 4 c_P / pi^4, UIUC static c_P = {STATIC_CP} (estimate; "
                     f"{src} has no torque)")
    c = speed.coeffs
    note = f"{src}: power-law fit Omega(b) = a0 b^a1 + a2 rad/s, rmse {speed.rmse:.3g} rad/s"
    return thrust.coefficient, cq, (c["a0"], c["a1"], c["a2"]), lines, note


def write_new_vehicle(path, name: str, **numbers) -> VehicleSpec:
    """Write :func:`new_vehicle_toml` atomically to ``path`` and return the loaded vehicle."""
    path = Path(path)
    text = new_vehicle_toml(name, src=f"{path} (not written)", **numbers)
    atomic.write_text(path, text)
    return parse_vehicle(tomllib.loads(text), path, PHYSICS_DT_S)


def axis_rate_gain(v: VehicleSpec, axis: str) -> float:
    """Rigid-body rate gain of ``axis`` at hover, (deg/s^2) per % of axis command: moment per % over inertia.

    Roll/pitch: ``axis_lever_m(axis) dT/d%`` (``VehicleSpec.axis_lever_m``); yaw: every rotor gets half the
    command with its spin's sign, ``n 0.5 (Q/T) dT/d%`` (the rotor-inertia reaction, a faster zero, is left out).
    """
    dT = v.thrust_gain() * v.dctrl_dcommand()  # N per % per rotor
    if axis == "yaw":
        moment = v.n_rotors * 0.5 * v.rotor.torque_to_thrust_m * dT
    else:
        moment = v.axis_lever_m(axis) * dT
    return moment / v.inertia_kgm2[{"roll": 0, "pitch": 1, "yaw": 2}[axis]] * 180.0 / math.pi


def baseline_gains(v: VehicleSpec, name: str = "standard", max_crossover_rad_s: float = 40.0) -> GainSet:
    """A first cascade for a new twin, designed by hand on ``b / s`` with the motor lag and delay.

    Rate loop PI: crossover ``w_c`` where the motor lag, the delay and half a flight-software period take 40 deg
    (``atan(w_c tau) + w_c (T_d + dt/2) = 40 deg``, at most ``max_crossover_rad_s``), ``kp = w_c / b``,
    ``ki = kp w_c / 5`` (the integrator costs 11 deg: phase margin about 39 deg). Angle loop P: ``kp = w_c / 5``.
    Yaw: the same rule at a quarter of the crossover. A starting point for tuning, not a tuned set.
    """
    tau, td = max(v.rotor.lag_s), max(v.rotor.delay_s) + 0.5 * v.control_dt_s
    lo, hi = 0.0, max_crossover_rad_s
    if math.atan(hi * tau) + hi * td > math.radians(40.0):
        for _ in range(60):  # bisection: the phase lag rises monotonically with w
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if math.atan(mid * tau) + mid * td < math.radians(40.0) else (lo, mid)
    wc = hi
    axes = {}
    for axis, w in (("pitch", wc), ("roll", wc), ("yaw", wc / 4.0)):
        kp = w / axis_rate_gain(v, axis)
        axes[axis] = AxisGains(outer=LoopGains(kp=w / 5.0), inner=LoopGains(kp=kp, ki=kp * w / 5.0))
    return GainSet(name=name, axes=axes)
