"""TUHH H-inf design against the published figures (ref. 002), Glover-McFarlane and SIMC against analytic
results."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.errors import DataError, UnknownNameError
from rotorlab.gains import LoopGains
from rotorlab.tune.antiwindup import simulate_saturated_loop
from rotorlab.tune.loopshaping import (
    glover_mcfarlane,
    hinf_mixed_sensitivity,
    modified_pid,
    tuhh_axis_plant,
    tuhh_torque_gain,
)
from rotorlab.tune.simc import half_rule, simc_pid

DT = 0.001


def test_torque_gain_from_published_coefficients():
    # by hand: Omega_H = 701.2 * 0.6^0.8069 - 34.15, Gamma = 701.2 * 0.8069 * 0.6^-0.1931,
    # dT/db = 2 C_T rho pi R^4 Omega_H Gamma, K = 0.23 dT/db
    omega_h = 701.2 * 0.6 ** 0.8069 - 34.15
    gamma = 701.2 * 0.8069 * 0.6 ** (0.8069 - 1)
    assert omega_h == pytest.approx(430.19, abs=0.01)
    expected = 0.23 * 2 * 0.0157 * 1.225 * math.pi * 0.127 ** 4 * omega_h * gamma
    assert tuhh_torque_gain("pitch") == pytest.approx(expected, rel=1e-12)
    assert tuhh_torque_gain("roll") == pytest.approx(1.942, abs=1e-3)
    with pytest.raises(UnknownNameError):
        tuhh_torque_gain("heave")


def test_axis_plant_matches_published_transfer_function():
    w = np.array([0.5, 3.0, 20.0, 80.0])
    s = 1j * w
    for axis, J, p in (("roll", 0.0181, 27.106), ("pitch", 0.0196, 26.963)):
        G = tuhh_axis_plant(axis, delay=False)
        K = tuhh_torque_gain(axis)
        H = lti.freqresp(G, w)
        angle = K * p / (s + p) / (J * s ** 2)
        assert np.allclose(H[:, 0, 0], angle, rtol=1e-10)
        assert np.allclose(H[:, 1, 0], angle * s, rtol=1e-10)
    yaw = lti.freqresp(tuhh_axis_plant("yaw", delay=False), w)[:, 0, 0]
    assert np.allclose(yaw, tuhh_torque_gain("yaw") * 7.171 / (s + 7.171) * (s + 2.434) / (0.0273 * s ** 2))


@pytest.fixture(scope="module")
def pitch_hinf():
    return hinf_mixed_sensitivity("pitch")


def _step(K, r_deg=10.0):
    G = tuhh_axis_plant("pitch", delay=False)
    out = simulate_saturated_loop(G, K, 2.0, DT, r=math.radians(r_deg), delay_s=0.028)
    y = np.degrees(out["y"][:, 0])
    t = out["t"]
    return t[np.argmax(y >= 0.9 * r_deg)] - t[np.argmax(y >= 0.1 * r_deg)], (y.max() - r_deg) / r_deg * 100, y


def _disturbance_peak_deg(K, d=0.1):
    G = tuhh_axis_plant("pitch", delay=False)
    out = simulate_saturated_loop(G, K, 4.0, DT, d=d, delay_s=0.028)
    return np.degrees(np.abs(out["y"][:, 0])).max(), np.degrees(out["y"][-1, 0])


def test_hinf_design_reaches_published_rise_time(pitch_hinf):
    K, gamma = pitch_hinf
    assert K.ninputs == 2 and K.noutputs == 1 and gamma < 1.0
    rise, overshoot, y = _step(K)
    # ref. 002 fig. 5: ~200 ms rise on a 10 deg step, little overshoot (simulated on the exact 28 ms delay)
    assert 0.15 <= rise <= 0.25
    assert overshoot < 5.0
    # the sensitivity weight's near-integrator (pole at 5e-4 rad/s) leaves a slow tail: within 2 % at 2 s
    assert abs(y[-1] - 10.0) < 0.2


def test_hinf_rejects_input_disturbance_much_better_than_modified_pid(pitch_hinf):
    K, _ = pitch_hinf
    pid = modified_pid(0.45, 0.3, 0.08)  # tuned here for a comparable ~180 ms rise time
    rise_pid, _, _ = _step(pid)
    assert 0.15 <= rise_pid <= 0.25
    peak_hinf, end_hinf = _disturbance_peak_deg(K)
    peak_pid, _ = _disturbance_peak_deg(pid)
    # ref. 002 fig. 6: 10 % disturbance -> H-inf ~4 deg, modified PID ~15 deg. Our reconstruction of the
    # weights rejects it better than published (about 1.6 deg); the PID reproduces the ~15 deg.
    assert 12.0 <= peak_pid <= 18.0
    assert peak_hinf <= 4.0
    assert peak_hinf < peak_pid / 3.0
    assert abs(end_hinf) < 0.05  # integral action: the disturbance is rejected in steady state


def test_glover_mcfarlane_integrator_analytic():
    # G = 1/s: X = Z = 1 so gamma_min = sqrt(2), eps_max = 1/sqrt(2)
    K, eps, gamma = glover_mcfarlane(ct.tf(1, [1, 0]))
    assert eps == pytest.approx(1 / math.sqrt(2), rel=1e-10)
    assert gamma == pytest.approx(1.1 * math.sqrt(2), rel=1e-10)
    w = np.geomspace(1e-3, 1e3, 4000)
    g = 1 / (1j * w)
    k = -lti.freqresp(K, w)[:, 0, 0]  # the positive-feedback K_inf
    S = 1 / (1 - g * k)
    M = np.array([[S, S * g], [k * S, k * S * g]]).transpose(2, 0, 1)
    achieved = np.linalg.norm(M, 2, axis=(1, 2)).max()
    assert math.sqrt(2) - 1e-6 <= achieved <= gamma + 1e-9


def test_glover_mcfarlane_on_tuhh_pitch_stabilises_with_delay():
    G = tuhh_axis_plant("pitch", pade_order=3)[0, 0]
    W1 = ct.tf([1.0, 4.0], [1.0, 1e-3]) * 0.2  # PI-like pre-compensator for low-frequency gain
    K, eps, _ = glover_mcfarlane(G, W1=W1)
    assert 0.2 < eps < 1.0
    cl = ct.feedback(ct.series(K, G), 1)
    assert lti.is_stable(cl)
    with pytest.raises(DataError, match="gamma_factor"):
        glover_mcfarlane(G, gamma_factor=1.0)
    with pytest.raises(DataError, match="continuous"):
        glover_mcfarlane(ct.tf(1, [1, -0.5], 0.1))


def test_simc_foptd_and_sopdt_rules():
    G = ct.tf(1, [10, 1]) * ct.tf(1, [2, 1]) * ct.tf(1, [0.5, 1])
    m = half_rule(G, delay_s=1.0)
    assert (m.tau1_s, m.theta_s) == pytest.approx((11.0, 2.5))  # 10 + 2/2, 1 + 2/2 + 0.5
    pi = simc_pid(G, delay_s=1.0, controller="pi")
    assert isinstance(pi, LoopGains)
    assert (pi.kp, pi.ki, pi.kd) == pytest.approx((2.2, 0.2, 0.0))  # kc = 11/5, tau_I = min(11, 20)
    pid = simc_pid(G, delay_s=1.0)  # SOPTD: tau1 = 10, tau2 = 2.25, theta = 1.25; kc = 4, tau_I = 10
    assert (pid.kp, pid.ki, pid.kd) == pytest.approx((4.0 * (1 + 0.225), 0.4, 9.0))


def test_simc_integrating_and_tuhh_double_integrator():
    g = simc_pid(ct.tf(2, [1, 0]), tau_c=0.2, delay_s=0.1, controller="pi")
    assert (g.kp, g.ki) == pytest.approx((1 / (2 * 0.3), 1 / (2 * 0.3) / 1.2))
    G = tuhh_axis_plant("pitch", delay=False)[0, 0]
    m = half_rule(ct.tf(G), delay_s=0.028, second_order=True)
    assert m.n_int == 2 and m.k == pytest.approx(tuhh_torque_gain("pitch") / 0.0196, rel=1e-6)
    assert m.theta_s == pytest.approx(0.028 + 1 / 26.963, rel=1e-6)
    gains = simc_pid(ct.tf(G), delay_s=0.028)
    K = ct.tf([gains.kd + gains.kp * gains.tf, gains.kp + gains.ki * gains.tf, gains.ki], [gains.tf, 1, 0])
    cl = ct.feedback(ct.series(K, lti.with_io_delay(G, 0.028, pade_order=5)), 1)
    assert lti.is_stable(cl)
    with pytest.raises(DataError, match="derivative"):
        simc_pid(ct.tf(G), delay_s=0.028, controller="pi")
    with pytest.raises(DataError, match="unstable"):
        simc_pid(ct.tf(1, [1, -1]), delay_s=0.1)
