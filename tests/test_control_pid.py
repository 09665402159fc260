"""DiscretePID against the transfer functions of rotorlab.lti, anti-windup, bumpless reset and gain switching."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab.errors import ConfigError
from rotorlab.gains import LoopGains
from rotorlab.lti import pid2_ss, pid_tf
from rotorlab.sim.control.pid import DiscretePID

DT = 0.02
# published gains (reference 000): P2-A2 standard inner PID / outer PD, A2-MINI/B 2-DoF optimal inner and outer
STD_INNER = LoopGains(kp=0.257, ki=0.643, kd=0.0231, tf=0.0225)
STD_OUTER = LoopGains(kp=9.26, kd=1.11, tf=0.03)
MINI_INNER = LoopGains(kp=0.5253, ki=1.7525, kd=0.0144, tf=0.0206, b=0.5787, c=1.0)
MINI_OUTER = LoopGains(kp=19.8566, kd=1.5331, tf=0.0723, b=0.9986, c=0.0)


def _signals(n=400, seed=0):
    rng = np.random.default_rng(seed)
    r = np.repeat(rng.normal(0, 5, n // 20), 20)  # piecewise-constant set-point: exercises the kicks
    y = np.cumsum(rng.normal(0, 0.3, n))
    return r, y


def _run(pid, r, y):
    return np.array([pid.step(rk, yk) for rk, yk in zip(r, y)])


@pytest.mark.parametrize("g", [STD_INNER, STD_OUTER, MINI_INNER, MINI_OUTER,
                               LoopGains(kp=1.3, ki=0.7), LoopGains(kp=0.0, ki=2.0)],
                         ids=["PID", "PD", "PID-2dof", "PD-2dof-c0", "PI", "I"])
def test_matches_pid2_ss_forced_response(g):
    r, y = _signals()
    C = pid2_ss(g.kp, g.ki, g.kd, g.tf, g.b, g.c, DT)
    t = np.arange(r.size) * DT
    ref = ct.forced_response(C, t, np.vstack([r, y])).outputs
    out = _run(DiscretePID(g, DT, antiwindup=None), r, y)
    np.testing.assert_allclose(out, np.ravel(ref), rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(ref))))


def test_one_dof_error_driven_matches_pid_tf():
    rng = np.random.default_rng(1)
    e = rng.normal(0, 1, 300)
    g = STD_INNER
    C = pid_tf(g.kp, g.ki, g.kd, g.tf, DT)
    ref = ct.forced_response(C, np.arange(e.size) * DT, e).outputs
    out = _run(DiscretePID(g, DT), e, np.zeros_like(e))
    np.testing.assert_allclose(out, ref, atol=1e-12)


def test_derivative_kick_first_sample():
    # c = 1: derivative on error, a unit set-point step moves the first output by kp b + kd / tf
    pid = DiscretePID(MINI_INNER, DT)
    u0 = pid.step(1.0, 0.0)
    assert u0 == pytest.approx(MINI_INNER.kp * MINI_INNER.b + MINI_INNER.kd / MINI_INNER.tf, rel=1e-12)
    # c = 0: no kick from the derivative
    pd = DiscretePID(MINI_OUTER, DT)
    assert pd.step(1.0, 0.0) == pytest.approx(MINI_OUTER.kp * MINI_OUTER.b, rel=1e-12)


def _saturated_loop(antiwindup, n=500):
    """PI (kp 1, ki 3) on the plant 1/(s + 1) with |u| <= 1 and a set-point of 0.9: the loop saturates
    during the rise, the textbook windup case (Astrom & Hagglund)."""
    pid = DiscretePID(LoopGains(kp=1.0, ki=3.0), DT, -1.0, 1.0, antiwindup=antiwindup)
    a = math.exp(-DT)  # exact ZOH discretisation of 1/(s + 1)
    y, ys, xi = 0.0, [], []
    for _ in range(n):
        u = pid.step(0.9, y)
        y = a * y + (1.0 - a) * u
        ys.append(y)
        xi.append(pid.xi)
    return np.array(ys), np.array(xi)


def _settling_time(y, target, band=0.02):
    bad = np.nonzero(np.abs(y - target) > band * target)[0]
    return (bad[-1] + 1) * DT


@pytest.mark.parametrize("aw", ["clamp", "backcalc"])
def test_antiwindup_bounds_integrator_and_recovers_faster(aw):
    y_no, xi_no = _saturated_loop(None)
    y_aw, xi_aw = _saturated_loop(aw)
    # without anti-windup the integral state winds up to twice what the saturation can ever use
    assert np.max(np.abs(xi_no)) > 2.0
    # with it, the integral stays within the output range (+ one sample of integration, ki dt e <= 0.054)
    assert np.max(np.abs(xi_aw)) <= 1.0 + 3.0 * DT * 0.9
    # overshoot: ~11 % with windup, < 4 % without; settling to 2 %: 7.6 s vs ~3.5 s
    assert (np.max(y_no) - 0.9) / 0.9 > 0.09
    assert (np.max(y_aw) - 0.9) / 0.9 < 0.04
    assert _settling_time(y_aw, 0.9) < 0.6 * _settling_time(y_no, 0.9)


def test_unsaturated_antiwindup_changes_nothing():
    r, y = _signals(seed=3)
    outs = [_run(DiscretePID(STD_INNER, DT, -1e6, 1e6, antiwindup=aw), r, y) for aw in ("clamp", "backcalc", None)]
    np.testing.assert_array_equal(outs[0], outs[2])
    np.testing.assert_allclose(outs[1], outs[2], atol=1e-12)


def test_bumpless_reset():
    pid = DiscretePID(MINI_INNER, DT)
    pid.reset(u0=7.5, y0=3.0, r0=4.0)
    assert pid.step(4.0, 3.0) == pytest.approx(7.5, abs=1e-12)
    # held inputs: the derivative starts at rest, so only the integral moves (by ki dt e per sample)
    assert pid.step(4.0, 3.0) == pytest.approx(7.5 + MINI_INNER.ki * DT * 1.0, abs=1e-12)


def test_gain_switch_is_bumpless_for_held_inputs_and_small_in_closed_loop():
    pid = DiscretePID(STD_INNER, DT)
    for _ in range(30):
        pid.step(2.0, 1.2)
    u_before = pid.step(2.0, 1.2)
    # the old controller carrying on: what the switched one must reproduce while the inputs are held
    ref = DiscretePID(STD_INNER, DT)
    for _ in range(31):
        ref.step(2.0, 1.2)
    u_old_next = ref.step(2.0, 1.2)
    pid.set_gains(MINI_INNER)
    u_new_next = pid.step(2.0, 1.2)
    assert u_new_next == pytest.approx(u_old_next, abs=1e-12)
    assert abs(u_new_next - u_before) < 0.1

    # closed loop on a first-order plant with a moving set-point: the switch jump is much smaller than a
    # naive switch (new controller started from zero state)
    def loop(switch):
        a = math.exp(-DT / 0.3)
        pid = DiscretePID(STD_INNER, DT, -30, 30)
        y, us = 0.0, []
        for k in range(300):
            if k == 150:
                switch(pid)
            u = pid.step(10.0 * math.sin(0.02 * k), y)
            y = a * y + (1 - a) * 2.0 * u
            us.append(u)
        return abs(us[150] - us[149])

    jump_bumpless = loop(lambda p: p.set_gains(MINI_INNER))
    jump_naive = loop(lambda p: (p.set_gains(MINI_INNER), p.reset()))
    assert jump_bumpless < 0.1 * jump_naive


def test_bad_arguments_name_the_field():
    with pytest.raises(ConfigError, match="tf"):
        DiscretePID(LoopGains(kp=1.0, kd=1.0, tf=0.005), DT)  # tf < dt/2: unstable forward-Euler filter
    with pytest.raises(ConfigError, match="antiwindup"):
        DiscretePID(STD_INNER, DT, antiwindup="magic")
    with pytest.raises(ConfigError, match="dt"):
        DiscretePID(STD_INNER, 0.0)
