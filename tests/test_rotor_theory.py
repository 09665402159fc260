"""Rotor derivatives: every number in a vehicle TOML against its blade-element / flapping formula
(``rotorlab.vehicles.rotor_theory``), and the formulas against the twin's own MuJoCo forces."""

import math

import mujoco
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.config import read_toml
from rotorlab.errors import ConfigError
from rotorlab.scenes import PREFIX, build_scene
from rotorlab.sim.linearize import linearize
from rotorlab.vehicles import G0, RHO_AIR, load_vehicle, parse_vehicle, vehicle_path
from rotorlab.vehicles.calibrate import hub_damping_range
from rotorlab.vehicles.rotor_theory import hover, thrust_slope_N_per_rad

ANTEOS = ["anteos-p2a2", "anteos-a2minib"]


def test_p2a2_hover_state_from_published_data():
    # MTOW 5 kg, R = 0.27 m, Omega = 316 rad/s: tip speed 85 m/s, C_T 0.006, inflow ratio 0.055 (issue #11)
    h = hover(load_vehicle("anteos-p2a2"))
    assert h.thrust_N == pytest.approx(5.0 * G0 / 4)
    assert h.tip_speed_mps == pytest.approx(85.32, abs=0.01)
    assert h.thrust_coefficient == pytest.approx(12.2625 / (RHO_AIR * math.pi * 0.27**2 * 85.32**2), rel=1e-6)
    assert h.thrust_coefficient == pytest.approx(0.0060, abs=1e-4)
    assert h.inflow_ratio == pytest.approx(0.0548, abs=2e-4)
    # theta_0 closes the blade-element thrust equation C_T = (sigma a / 2)(theta_0 / 3 - lambda / 2)
    r = load_vehicle("anteos-p2a2").rotor
    assert r.solidity * r.lift_slope_per_rad / 2 * (h.collective_rad / 3 - h.inflow_ratio / 2) == \
        pytest.approx(h.thrust_coefficient, rel=1e-9)


@pytest.mark.parametrize("vehicle", ANTEOS + ["tuhh-quad"])
def test_toml_derivatives_are_the_theory(vehicle):
    v = load_vehicle(vehicle)
    h = hover(v)
    r = v.rotor
    assert r.hforce_N_per_mps == pytest.approx(h.hforce_N_per_mps, rel=0.01)
    assert r.flap_arm_m == pytest.approx(h.flap_arm_m, rel=0.01, abs=1e-9)
    if vehicle in ANTEOS:  # the TUHH identified model has no rotor damping (its README)
        assert r.axial_damping_N_per_mps == pytest.approx(h.axial_damping_N_per_mps, rel=0.01)
        # calibrated hub within the theory ranges: flap frequency ratio 1-1.5, hub damping per rotor
        assert 1.0 < h.flap_frequency_ratio < 1.5
        lo, hi = hub_damping_range(v)
        assert lo <= r.hub_damping_Nms_per_rad <= hi
        # the calibrated thrust slope is the BEMT one within 10 %
        assert r.thrust_slope_N_per_rad == pytest.approx(thrust_slope_N_per_rad(v), rel=0.10)
    assert 0.06 <= r.solidity <= 0.10 and 1.0 <= r.lock_number <= 4.0


def test_p2a2_speed_derivatives_in_theory_ranges():
    v = load_vehicle("anteos-p2a2")
    h = hover(v)
    x_u = -v.n_rotors * h.hforce_N_per_mps / v.mass_kg
    m_u = v.n_rotors * (h.hub_moment_Nm_per_mps + h.hforce_N_per_mps * v.rotor_height_m)
    assert -0.08 < x_u < -0.02  # 1/s
    assert 0.02 < m_u < 0.13  # N m/(m/s)


def _hovering(vehicle: str):
    """The vehicle, its free-flight scene, model and data at the hover keyframe."""
    v = load_vehicle(vehicle)
    sc = build_scene("free-flight", v)
    d = mujoco.MjData(sc.model)
    mujoco.mj_resetDataKeyframe(sc.model, d, 0)
    return v, sc, sc.model, d


@pytest.mark.parametrize("vehicle", ANTEOS + ["tuhh-quad"])
def test_twin_forces_are_the_derivatives(vehicle):
    """Forward airspeed on the hovering twin: MuJoCo's actuator forces are -4 dH/du and the hub moments."""
    v, sc, m, d = _hovering(vehicle)
    u = 0.2  # m/s headwind on every rotor (the wind input of the H-force actuators)
    d.ctrl[sc.aero_actuators["hx"]] = u
    mujoco.mj_forward(m, d)
    f = d.qfrc_actuator[:6]  # free joint: world force, body torque
    assert f[0] == pytest.approx(v.n_rotors * v.rotor.hforce_N_per_mps * u, rel=1e-6)
    # pitch (FLU y) moment about the CG: hub moment plus the H-force at the hub height
    my = v.n_rotors * v.rotor.hforce_N_per_mps * u * (v.rotor.flap_arm_m + v.rotor_height_m)
    assert f[4] == pytest.approx(my, rel=1e-3, abs=1e-9)


@pytest.mark.parametrize("vehicle", ANTEOS)
def test_rig_dc_gain_is_control_over_rotor_damping(vehicle):
    """Low-frequency pitch damping = thrust damping 2 l^2 (-dT/dw) + the four hubs' damping (+ the bearing)."""
    v = load_vehicle(vehicle)
    r = v.rotor
    G = linearize("pitch-rig", v, "pitch", "gyro_pitch", delay=False)
    dc = lti.freqresp(G, np.array([1e-3]))[0, 0, 0].real  # deg/s per %
    m_u = v.arm_m * r.thrust_slope_N_per_rad * r.blade_pitch_per_pct_rad  # N m per %
    damping = 2 * v.arm_m**2 * r.axial_damping_N_per_mps + v.n_rotors * r.hub_damping_Nms_per_rad \
        + v.rigs["pitch"].bearing_damping_Nms_per_rad + v.n_rotors * r.hforce_N_per_mps * v.rotor_height_m**2
    assert dc == pytest.approx(math.degrees(m_u / damping), rel=0.01)


@pytest.mark.parametrize("vehicle", ANTEOS)
def test_hub_element_moments(vehicle):
    """A disc tilted against its hub spring: hinge torque = K_hub * angle; the air damps its tilt rate by D."""
    v, _, m, d = _hovering(vehicle)
    j = m.joint(f"{PREFIX}flap1_y")
    d.qpos[j.qposadr[0]] = 0.01
    d.qvel[j.dofadr[0]] = 0.1
    mujoco.mj_forward(m, d)
    r = v.rotor
    k = j.dofadr[0]
    assert d.qfrc_spring[k] + d.qfrc_damper[k] == pytest.approx(-r.hub_stiffness_Nm_per_rad * 0.01
                                                                - r.hub_spring_damping_Nms_per_rad * 0.1, rel=1e-9)
    a = m.actuator(f"{PREFIX}tilt1_y").id
    assert d.actuator_force[a] == pytest.approx(-r.hub_damping_Nms_per_rad * 0.1, rel=1e-9)


@pytest.mark.parametrize("key, value", [("blades", 2.5), ("solidity", 0.0), ("lock_number", 0.0)])
def test_hub_without_blade_data_is_a_config_error(key, value):
    data = read_toml(vehicle_path("anteos-p2a2"), "vehicle")
    data = {**data, "rotor": {**data["rotor"], key: value}}
    with pytest.raises(ConfigError, match=f"rotor.{key}"):
        parse_vehicle(data, "bad.toml")
