"""The digital twins against their ground truth: published identified models, the TUHH per-axis model and
thrust data, the designed delay and IMU-mount resonance."""

import dataclasses
import math

import control as ct
import mujoco
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator
from rotorlab.vehicles import load_vehicle
from rotorlab.vehicles.calibrate import closed_form

W_BAND = np.logspace(0.0, np.log10(15.0), 30)


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_pitch_rig_matches_published_model(vehicle):
    v = load_vehicle(vehicle)
    pm = v.published["testbed"]
    G = linearize("pitch-rig", vehicle, "pitch", "gyro_pitch", delay=False)
    ratio = lti.freqresp(G, W_BAND)[:, 0, 0] / lti.freqresp(ct.tf(pm.num, pm.den), W_BAND)[:, 0, 0]
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 1.0
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 5.0


def _band_error(G, pm, w):
    ratio = lti.freqresp(G, w)[:, 0, 0] / lti.freqresp(ct.tf(pm.num, pm.den), w)[:, 0, 0]
    return np.max(np.abs(20 * np.log10(np.abs(ratio)))), np.max(np.abs(np.degrees(np.angle(ratio))))


def test_free_flight_matches_published_flight_model():
    """The rig calibration carries over: the twin's true free-flight pitch response is the published in-flight
    PBSID model within 3 dB and 20 deg over 2-15 rad/s (where the PRBS data are)."""
    v = load_vehicle("anteos-p2a2")
    G = linearize("free-flight", v, "pitch", "gyro_pitch", delay=False)
    db, deg = _band_error(G, v.published["flight"], np.logspace(np.log10(2.0), np.log10(15.0), 30))
    assert db < 3.0 and deg < 20.0


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_hover_pitch_speed_mode_is_slow(vehicle):
    """The hover pitch/speed oscillation (rotor speed derivatives against rotor + hub damping) doubles in no
    less than 5 s, or is stable."""
    G = linearize("free-flight", vehicle, "pitch", "gyro_pitch", delay=False)
    ev = np.log(np.linalg.eigvals(np.asarray(G.A)).astype(complex)) / G.dt
    ev = ev[np.abs(ev) > 1e-6]  # position and heading are neutral
    growth = ev.real.max()
    assert growth <= 0.0 or math.log(2) / growth >= 5.0


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_rig_bearing_shapes_nothing(vehicle):
    """Rig independence: without the bearing's damping the 3-15 rad/s response moves by less than 1 dB."""
    v = load_vehicle(vehicle)
    rig = dataclasses.replace(v.rigs["pitch"], bearing_damping_Nms_per_rad=0.0)
    free = dataclasses.replace(v, rigs={**v.rigs, "pitch": rig})
    w = np.logspace(np.log10(3.0), np.log10(15.0), 25)
    a = lti.freqresp(linearize("pitch-rig", v, "pitch", "gyro_pitch", delay=False), w)[:, 0, 0]
    b = lti.freqresp(linearize("pitch-rig", free, "pitch", "gyro_pitch", delay=False), w)[:, 0, 0]
    assert np.max(np.abs(20 * np.log10(np.abs(a / b)))) < 1.0
    assert np.max(np.abs(np.degrees(np.angle(a / b)))) < 5.0


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_calibration_closed_form_is_exact_for_massless_discs(vehicle):
    """The closed form solves the massless-disc structure to the published coefficients (analytic check)."""
    v = load_vehicle(vehicle)
    pm = v.published["testbed"]
    slope, k, c, d = closed_form(v)  # per rotor
    n = v.n_rotors
    K, C, D = n * k, n * c, n * d
    J = v.inertia_kgm2[1] + v.rigs["pitch"].ring_inertia_kgm2
    d_a = 2 * v.arm_m**2 * v.rotor.axial_damping_N_per_mps
    m_u = math.degrees(v.arm_m * slope * v.rotor.blade_pitch_per_pct_rad)
    G = ct.tf([m_u * (D + C), m_u * K], [J * (D + C), J * K + d_a * (D + C) + D * C, (d_a + D) * K])
    w = np.logspace(-1, 2, 20)
    np.testing.assert_allclose(lti.freqresp(G, w)[:, 0, 0], lti.freqresp(ct.tf(pm.num, pm.den), w)[:, 0, 0],
                               rtol=1e-9)
    assert min(k, c, d) > 0


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_linear_delay_is_three_samples(vehicle):
    G0 = linearize("pitch-rig", vehicle, "pitch", "gyro_pitch", delay=False)
    G1 = linearize("pitch-rig", vehicle, "pitch", "gyro_pitch", delay=True)
    w = np.array([2.0, 8.0])
    ratio = lti.freqresp(G1, w)[:, 0, 0] / lti.freqresp(G0, w)[:, 0, 0]
    np.testing.assert_allclose(ratio, np.exp(-1j * w * 0.06), rtol=1e-6, atol=1e-6)


def _tuhh_axis_model(v, J, p, Td):
    """TUHH eq. 13: angle/command = K |p|/(s+|p|) e^(-s Td) / (J s^2); command in % of b, angle in deg.

    K is the moment per unit differential command: each rotor of the pair gets +-b/2, so
    K = arm * dT/db with dT/db = 2 k_T Omega_H dOmega/db at b_H = 0.6 (TUHH eqs. 3-4)."""
    r = v.rotor
    b = r.hover_command
    K = v.arm_m * 2 * r.k_thrust * float(r.speed(b)) * float(r.dspeed_db(b))
    return ct.tf([K * p / 100 * 180 / math.pi], [J, J * p, 0, 0]), K


@pytest.mark.parametrize("axis,J,p,Td", [("roll", 0.0181, 27.106, 0.024), ("pitch", 0.0196, 26.963, 0.028)])
def test_tuhh_axis_matches_identified_model(axis, J, p, Td):
    v = load_vehicle("tuhh-quad")
    M, K = _tuhh_axis_model(v, J, p, Td)
    assert K == pytest.approx(1.94, rel=0.01)  # N m per unit b, from C_T and the speed map
    w = np.logspace(np.log10(3.0), np.log10(40.0), 25)
    G = linearize(f"{axis}-rig", "tuhh-quad", axis, f"angle_{axis}", delay=True)
    ratio = lti.freqresp(G, w)[:, 0, 0] / (lti.freqresp(M, w)[:, 0, 0] * np.exp(-1j * w * Td))
    # inertia, torque gain, motor pole and delay together: magnitude within 5 %, phase within 3 deg
    assert np.max(np.abs(np.abs(ratio) - 1)) < 0.05
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 3.0


def test_tuhh_mass_hovers_at_published_command():
    v = load_vehicle("tuhh-quad")
    assert v.hover_thrust_N * 4 == pytest.approx(v.rotor.k_thrust * float(v.rotor.speed(0.6)) ** 2 * 4, rel=2e-3)


def _measured_delay_s(vehicle, step_pct=2.0, t_step=0.2, horizon_s=0.4):
    """Delay from a command step: the shift that best aligns the twin's gyro response (1 kHz) with the
    response of its own delay-free linearisation to the same step."""
    sim = Simulator("pitch-rig", vehicle, sensor_noise=False)
    m, d = sim.model, sim.data
    while sim.time < t_step - 1e-9:
        sim.tick()
    q0 = sim.measure()["q"]
    sim.set_commands([sim.vehicle.hover_collective_pct, 0.0, step_pct, 0.0])
    n = int(round(horizon_s / m.opt.timestep))
    q = np.empty(n)
    for k in range(n):
        mujoco.mj_step(m, d)
        q[k] = sim.measure()["q"] - q0
    G = linearize("pitch-rig", vehicle, "pitch", "gyro_pitch", delay=False)
    _, y = ct.forced_response(G, np.arange(n) * G.dt, np.full(n, step_pct))
    shifts = np.arange(0, 100)
    err = [np.sum((q[s:] - y[: n - s]) ** 2) for s in shifts]
    return shifts[int(np.argmin(err))] * m.opt.timestep, min(err) / np.sum(q**2)


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "anteos-a2minib"])
def test_step_delay_is_60_ms(vehicle):
    delay, rel_err = _measured_delay_s(vehicle)
    assert delay == pytest.approx(0.060, abs=1e-9)
    assert rel_err < 1e-3  # and the shifted linear response is the nonlinear one


def test_imu_mount_resonance_at_design_frequency():
    v = load_vehicle("anteos-p2a2")
    G = linearize("pitch-rig", "anteos-p2a2", "pitch", "gyro_pitch", delay=False)
    ev = np.log(np.linalg.eigvals(np.asarray(G.A)).astype(complex)) / G.dt
    ev = ev[np.abs(ev) > 1.0]  # the rig's free rotation is a pole at the origin
    wn = np.abs(ev)
    zeta = -ev.real / wn
    target = 2 * math.pi * v.imu.mount_frequency_hz
    k = np.argmin(np.abs(wn - target))
    assert wn[k] == pytest.approx(target, rel=0.03)
    assert zeta[k] == pytest.approx(v.imu.mount_damping_ratio, rel=0.2)


@pytest.mark.parametrize("b", [0.3, 0.6, 0.9])
def test_thrust_stand_reproduces_tuhh_thrust_curve(b):
    v = load_vehicle("tuhh-quad")
    sim = Simulator("thrust-stand", "tuhh-quad", sensor_noise=False)
    sim.set_rotor_commands([100 * b])
    for _ in range(int(round(1.0 / sim.control_dt_s))):  # 1 s: many motor time constants
        sim.tick()
    thrust, torque = sim.load_cell()
    omega = float(v.rotor.speed(b))
    expected = v.rotor.thrust_coefficient * 1.225 * math.pi * v.rotor.radius_m**4 * omega**2  # TUHH eq. 4
    assert thrust == pytest.approx(expected, rel=0.01)
    assert sim.rotor_speed_rad_s()[0] == pytest.approx(omega, rel=1e-3)
    q_expected = v.rotor.torque_coefficient * 1.225 * math.pi * v.rotor.radius_m**5 * omega**2  # TUHH eq. 5
    assert abs(torque) == pytest.approx(q_expected, rel=0.01)


def test_hover_keyframe_is_a_trim():
    sim = Simulator("free-flight", "anteos-p2a2", sensor_noise=False)
    z0 = sim.data.qpos[2]
    for _ in range(25):
        sim.set_commands([sim.vehicle.hover_collective_pct, 0, 0, 0])
        sim.tick()
    assert abs(sim.data.qpos[2] - z0) < 1e-4
    assert np.max(np.abs(sim.true_attitude_deg())) < 1e-3


def test_thrust_sweep_scenario_recovers_thrust_constant():
    v = load_vehicle("tuhh-quad")
    r = run_scenario("thrust-sweep", "tuhh-quad", options={"levels_pct": [30.0, 60.0, 90.0], "hold_s": 0.5})
    assert r.metrics["k_thrust_N_per_rad2_s2"] == pytest.approx(v.rotor.k_thrust, rel=1e-3)
    np.testing.assert_allclose(r.metrics["omega_rad_s"], v.rotor.speed(np.array([0.3, 0.6, 0.9])), rtol=1e-3)


def test_thrust_steps_scenario_recovers_motor_lag():
    r = run_scenario("thrust-steps", "tuhh-quad")
    # rotor 1 (pitch pair): 1/26.963 s; the stiff load cell adds a few ms of apparent delay, not lag
    assert r.metrics["time_constant_s"] == pytest.approx(1 / 26.963, rel=0.05)
    assert 0.028 <= r.metrics["delay_s"] <= 0.028 + 0.008
