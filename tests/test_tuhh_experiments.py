"""Ref. 002's experiments on the TUHH twin (rigs at the vehicle's 250 Hz): 10 deg steps, a 10 % input
disturbance and a saturating 30 % one, for the modified PID, the H-inf loop-shaping design and the H-inf design
with the Riccati anti-windup compensator; the rotor-inertia yaw reaction; why the attitude loop runs at 250 Hz."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.designs import DESIGNS, design
from rotorlab.scenes import build_scene
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import run_scenario
from rotorlab.vehicles import load_vehicle

STEP = {"steps_deg": [10.0], "small_step_deg": 0.0, "hold_s": 2.0, "t0_s": 0.5}


@pytest.fixture(scope="module")
def pitch_runs():
    out = {}
    for name in DESIGNS:
        ctl = design(name, "tuhh-quad")
        out[name] = {
            "step": run_scenario("setpoint", "tuhh-quad", scene="pitch-rig", controller=ctl, options=STEP,
                                 duration_s=2.5, seed=5),
            **{f: run_scenario("input-disturbance", "tuhh-quad", scene="pitch-rig", controller=ctl, seed=5,
                               duration_s=7.0, options={"fraction": f, "t0_s": 0.5}) for f in (0.1, 0.3)},
        }
    return out


def test_ten_degree_step_rises_in_about_200_ms(pitch_runs):
    # ref. 002 fig. 5: both designs rise in about 200 ms
    for name, runs in pitch_runs.items():
        st = runs["step"].metrics["steps"][0]
        assert runs["step"].stopped is None
        assert 0.15 <= st["rise_time_s"] <= 0.3, name
    assert pitch_runs["hinf-loopshaping"]["step"].metrics["steps"][0]["overshoot_pct"] < 10.0


def test_hinf_halves_the_modified_pid_deviation_under_10_percent(pitch_runs):
    # ref. 002 fig. 6: about 4 deg for H-inf against 15 deg for the modified PID, which recovers ~4 s later
    pid = pitch_runs["modified-pid"][0.1].metrics["pitch"]["disturbance"]
    hinf = pitch_runs["hinf-loopshaping"][0.1].metrics["pitch"]["disturbance"]
    assert 12.0 <= abs(pid["peak_deviation"]) <= 18.0
    assert abs(hinf["peak_deviation"]) <= 0.5 * abs(pid["peak_deviation"])
    assert pid["recovery_time_s"] - hinf["recovery_time_s"] > 2.0


def test_riccati_antiwindup_recovers_the_saturating_30_percent(pitch_runs):
    # ref. 002 fig. 8: without anti-windup the loop goes unstable (here: the rig stop), with it the angle returns
    plain, aw = pitch_runs["hinf-loopshaping"][0.3], pitch_runs["hinf-loopshaping-aw"][0.3]
    assert plain.stopped is not None and "rig stop" in plain.stopped
    assert aw.stopped is None
    d = aw.metrics["pitch"]["disturbance"]
    assert d["recovery_time_s"] is not None and abs(aw.log["theta"][-50:]).max() < 0.5
    assert np.abs(aw.log["u_lon"]).max() > 40.0 - 1e-9  # the command really saturated


def test_designs_are_stable_on_the_twin_at_its_rate_and_hinf_is_not_at_50_hz():
    # the twin's true pitch-rig model (1 kHz, delay included) sampled at the controller rate
    G = linearize("pitch-rig", "tuhh-quad", "pitch", ["angle_pitch", "gyro_pitch"], delay=True)
    for dt, expect in ((0.004, {n: True for n in DESIGNS}), (0.02, {"hinf-loopshaping": False})):
        n = int(round(dt / G.dt))
        Gd = ct.ss(*_downsample(G, n), dt)
        for name, stable in expect.items():
            spec = design(name, "tuhh-quad", axes=("pitch",), dt_s=dt)[0]
            K = ct.ss(spec.A, spec.B[:, 1:], spec.C, spec.D[:, 1:], dt)  # from [theta, q] with r = 0
            assert lti.is_stable(ct.feedback(Gd, K, sign=+1)) is stable, (name, dt)


def _downsample(G, n):
    """Zero-order-hold input over n fast steps: x+ = A^n x + sum A^i B u."""
    A, B = np.asarray(G.A), np.asarray(G.B)
    An, Bn = np.eye(A.shape[0]), np.zeros_like(B)
    for _ in range(n):
        Bn = A @ Bn + B
        An = A @ An
    return An, Bn, np.asarray(G.C), np.asarray(G.D)


def test_rotor_inertia_gives_the_published_yaw_zero():
    # ref. 002 eq. 1: yaw moment = drag torque + J_R dOmega/dt, a zero at s = -q/J_R (table 1: 2.434 1/s)
    v = load_vehicle("tuhh-quad")
    r = v.rotor
    omega_h = float(r.speed(r.hover_command))
    q = 2 * r.torque_coefficient * 1.225 * math.pi * r.radius_m ** 5 * omega_h  # dQ/dOmega at hover
    z = q / r.inertia_kgm2
    assert z == pytest.approx(2.434, rel=1e-3)
    G = linearize("free-flight", "tuhh-quad", "yaw", "gyro_yaw", delay=False)
    dT_dpct = v.thrust_gain() * v.dctrl_dcommand()
    p = 1.0 / np.mean(r.lag_s)
    w = np.geomspace(0.5, 30.0, 12)
    s = 1j * w
    # DC: 4 rotors x (command/2) x Q/T x dT/d% ; the zero lifts the response above z by (1 + s/z); the rotors'
    # in-plane drag (H-force k_h at the arm l) damps yaw rate with 4 k_h l^2
    J = v.inertia_kgm2[2]
    damping = 4 * r.hforce_N_per_mps * v.arm_m ** 2
    expected = 2 * r.torque_to_thrust_m * dT_dpct * (1 + s / z) * p / (s + p) / (J * s + damping) * 180 / math.pi
    ratio = lti.freqresp(G, w)[:, 0, 0] / expected
    assert np.abs(np.abs(ratio) - 1).max() < 0.03
    assert np.abs(np.angle(ratio, deg=True)).max() < 3.0
    # the ANTEOS twins (fixed RPM) have no spin-up reaction

    assert build_scene("pitch-rig", "anteos-p2a2").spinup_actuators.size == 0
