"""A loop logged slower than it runs: the lifted closed loop (ident.greybox.lift_interpolated) equals the loop
simulated at its own rate on the linearly interpolated reference, and the indirect fit recovers the plant from such
a log (noise-free data: the true parameters)."""

import control as ct
import numpy as np
import pytest

from rotorlab.ident.flightlogs.identify import loop_substeps, rate_plant_structure
from rotorlab.ident.greybox import _closed_loop, lift_interpolated, oe_fit_closed_loop

LOOP_DT, SUB = 1 / 400, 16
LOG_DT = LOOP_DT * SUB  # 25 Hz
TRUE = {"K": 900.0, "tau_s": 0.03, "delay_s": 0.006}


def _pid(dt):
    # a 2-input PID u = Cr r - Cy y with a filtered derivative on the measurement, at the loop rate
    s = ct.tf("s")
    Cr = 0.08 + 0.15 / s
    Cy = 0.08 + 0.15 / s + 0.003 * s / (1 + s / (2 * np.pi * 20))
    return ct.c2d(ct.ss(ct.tf([[Cr.num[0][0], (-Cy).num[0][0]]], [[Cr.den[0][0], Cy.den[0][0]]])), dt, "tustin")


def _slow_log(n=500, seed=1):
    rng = np.random.default_rng(seed)
    r = np.convolve(rng.standard_normal(n), np.ones(3) / 3, "same")  # pilot-like, smooth at 25 Hz
    r[:2] = 0.0  # the loop starts at rest (the lifted state xi = x - G1 r is zero then)
    t_slow = np.arange(n) * LOG_DT
    t_fast = np.arange((n - 1) * SUB + 1) * LOOP_DT
    r_fast = np.interp(t_fast, t_slow, r)
    plant = rate_plant_structure().discretize(LOOP_DT, TRUE)
    cl = _closed_loop(plant, _pid(LOOP_DT), 0)
    y_fast = ct.forced_response(cl, U=r_fast).outputs
    return r, np.atleast_2d(y_fast)[0, ::SUB], cl


def test_lifted_loop_equals_the_loop_run_between_samples():
    r, y, cl = _slow_log()
    lifted = lift_interpolated(cl, SUB)
    assert lifted.dt == pytest.approx(LOG_DT)
    y_lift = np.atleast_2d(ct.forced_response(lifted, U=r).outputs)[0]
    np.testing.assert_allclose(y_lift, y, atol=1e-9 * np.abs(y).max())
    # holding the set-point instead of interpolating it is another signal (the check above can fail)
    y_zoh = np.atleast_2d(ct.forced_response(cl, U=np.repeat(r, SUB)[: (len(r) - 1) * SUB + 1]).outputs)[0, ::SUB]
    assert np.abs(y_zoh - y).max() > 1e-3 * np.abs(y).max()


def test_indirect_fit_recovers_the_plant_from_a_slow_log():
    r, y, _ = _slow_log()
    C = _pid(LOOP_DT)
    assert loop_substeps(C, LOG_DT) == SUB
    res = oe_fit_closed_loop(rate_plant_structure(K=300.0, tau_s=0.05, delay_s=0.01), C, r, y, LOG_DT,
                             estimate_x0=True, cov="white", substeps=SUB)
    for k, v in TRUE.items():
        assert res.params[k] == pytest.approx(v, rel=1e-3), k
