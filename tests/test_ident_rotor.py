"""Rotor fits recover the published TUHH rotor data from synthetic thrust-stand logs."""

import math

import numpy as np
import pytest

from rotorlab.errors import DataError
from rotorlab.ident.greybox import simulate_greybox
from rotorlab.ident.rotor import (
    fit_first_order_steps,
    fit_pitch_thrust,
    fit_speed_map,
    fit_thrust_coefficient,
    fit_torque_coefficient,
)
from rotorlab.ident.structures import first_order_structure

RHO, R = 1.225, 0.127


def test_speed_map_power_law_recovers_tuhh_coefficients():
    rng = np.random.default_rng(0)
    b = np.linspace(0.1, 1.0, 60)
    omega = 701.2 * b**0.8069 - 34.15 + 2.0 * rng.standard_normal(b.size)
    fit = fit_speed_map(b, omega, "power")
    assert fit.coeffs["a0"] == pytest.approx(701.2, rel=0.01)
    assert fit.coeffs["a1"] == pytest.approx(0.8069, rel=0.01)
    assert fit.coeffs["a2"] == pytest.approx(-34.15, abs=3.0)
    for k, v in {"a0": 701.2, "a1": 0.8069, "a2": -34.15}.items():
        assert abs(fit.coeffs[k] - v) < 4 * fit.std[k]
    assert fit.slope(0.6) == pytest.approx(701.2 * 0.8069 * 0.6 ** (0.8069 - 1), rel=0.01)


def test_speed_map_polynomials_are_exact_on_polynomial_data():
    b = np.linspace(0, 1, 20)
    assert fit_speed_map(b, 3 + 400 * b, "linear").coeffs == pytest.approx({"c0": 3, "c1": 400})
    q = fit_speed_map(b, 3 + 400 * b - 50 * b**2, "quadratic")
    assert q.coeffs == pytest.approx({"c0": 3, "c1": 400, "c2": -50})
    with pytest.raises(DataError, match="b > 0"):
        fit_speed_map(b, 3 + 400 * b, "power")


def test_thrust_and_torque_coefficients():
    rng = np.random.default_rng(1)
    omega = np.linspace(100, 600, 40)
    A = math.pi * R**2
    T = 0.0157 * RHO * A * R**2 * omega**2 * (1 + 0.01 * rng.standard_normal(omega.size))
    Q = 0.0015 * RHO * A * R**3 * omega**2
    ft = fit_thrust_coefficient(omega, T, RHO, R)
    assert ft.coefficient == pytest.approx(0.0157, rel=0.01)
    assert abs(ft.coefficient - 0.0157) < 4 * ft.coefficient_std
    fq = fit_torque_coefficient(omega, power_W=Q * omega, rho=RHO, radius_m=R)
    assert fq.coefficient == pytest.approx(0.0015, rel=1e-9)


def test_variable_pitch_thrust_is_linear_in_blade_pitch():
    th = np.linspace(-0.1, 0.2, 15)
    f = fit_pitch_thrust(th, 20.0 + 150.0 * th)
    assert (f.intercept, f.slope) == pytest.approx((20.0, 150.0))


def test_first_order_motor_from_steps():
    rng = np.random.default_rng(2)
    dt = 0.002
    b = np.concatenate([np.full(100, 0.5), np.full(300, 0.6), np.full(300, 0.45), np.full(300, 0.55)])
    truth = first_order_structure(K=420.0, tau=0.037, delay_s=0.005)  # pole 27 1/s (TUHH), 2.5-sample delay
    omega = 300 + simulate_greybox(truth, b - 0.5, dt)[:, 0] + 0.5 * rng.standard_normal(b.size)
    fit = fit_first_order_steps(b, omega, dt, rng=0)
    assert fit.gain == pytest.approx(420.0, rel=0.02)
    assert fit.tau_s == pytest.approx(0.037, rel=0.05)
    assert fit.delay_s == pytest.approx(0.005, abs=0.001)
    assert fit.pole_rad_s == pytest.approx(27.0, rel=0.05)
