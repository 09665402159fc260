"""Metrics against analytic first- and second-order responses."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rotorlab.errors import DataError
from rotorlab.sim.metrics import control_metrics, disturbance_metrics, step_metrics

DT = 0.001


def test_first_order_step():
    tau, amp, t0 = 0.3, 4.0, 1.0
    t = np.arange(0.0, 6.0, DT)
    y = np.where(t >= t0, amp * (1.0 - np.exp(-(t - t0) / tau)), 0.0)
    m = step_metrics(t, y, amp, y0=0.0, t_step=t0)
    assert m["rise_time_s"] == pytest.approx(tau * math.log(9.0), abs=1e-5)  # 10 -> 90 %: tau ln 9
    assert m["settling_time_s"] == pytest.approx(tau * math.log(50.0), abs=1e-5)  # 2 %: tau ln 50
    assert m["overshoot_pct"] == 0.0
    assert m["steady_state_error"] == pytest.approx(amp * np.mean(np.exp(-(t[-250:] - t0) / tau)), rel=1e-9)


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7])
def test_second_order_step_negative_direction(zeta):
    wn, y0, yf = 6.0, 2.0, -3.0  # a downward step: metrics must not care about the sign
    wd = wn * math.sqrt(1 - zeta ** 2)
    phi = math.acos(zeta)

    def s(t):  # normalised unit-step response of wn^2 / (s^2 + 2 zeta wn s + wn^2)
        return 1.0 - math.exp(-zeta * wn * t) / math.sqrt(1 - zeta ** 2) * math.sin(wd * t + phi)

    t = np.arange(0.0, 12.0, DT)
    y = y0 + (yf - y0) * np.array([s(tk) for tk in t])
    m = step_metrics(t, y, yf, y0=y0)
    os_exact = 100.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    assert m["overshoot_pct"] == pytest.approx(os_exact, rel=1e-5)
    assert m["peak_time_s"] == pytest.approx(math.pi / wd, abs=DT)
    t_pk = math.pi / wd
    rise = brentq(lambda x: s(x) - 0.9, 0, t_pk) - brentq(lambda x: s(x) - 0.1, 0, t_pk)
    assert m["rise_time_s"] == pytest.approx(rise, abs=1e-5)
    # settling: last crossing of the 2 % band, found on a fine grid of the analytic response
    tf = np.arange(0.0, 12.0, 1e-5)
    sf = 1.0 - np.exp(-zeta * wn * tf) / math.sqrt(1 - zeta ** 2) * np.sin(wd * tf + phi)
    ts = tf[np.nonzero(np.abs(sf - 1.0) > 0.02)[0][-1]]
    assert m["settling_time_s"] == pytest.approx(ts, abs=2e-4)
    # the tail (last 5 %, from 11.4 s) is inside the decaying envelope of the 5-unit step
    assert abs(m["steady_state_error"]) < 5.0 * math.exp(-zeta * wn * 11.4) / math.sqrt(1 - zeta ** 2)


def test_step_never_reaching_gives_nan():
    t = np.arange(0, 1, 0.01)
    m = step_metrics(t, 0.5 * np.ones_like(t), 1.0)
    assert math.isnan(m["rise_time_s"]) and math.isnan(m["settling_time_s"])
    assert m["steady_state_error"] == pytest.approx(0.5)


def test_disturbance_response_critically_damped():
    # y = -A (t - td) exp(-(t - td)/tau): the response of 1/(tau s + 1)^2 to an impulse; peak at tau, A tau/e
    A, tau, td, ref = 30.0, 0.4, 2.0, 1.0
    t = np.arange(0.0, 10.0, DT)
    x = np.clip(t - td, 0, None)
    y = ref - A * x * np.exp(-x / tau)
    m = disturbance_metrics(t, y, td, ref=ref)
    assert m["peak_deviation"] == pytest.approx(-A * tau / math.e, rel=1e-6)
    assert m["peak_time_s"] == pytest.approx(tau, abs=DT)
    band = 0.05 * A * tau / math.e
    t_rec = brentq(lambda s: A * s * math.exp(-s / tau) - band, tau, 20 * tau)
    assert m["band"] == pytest.approx(band, rel=1e-6)
    assert m["recovery_time_s"] == pytest.approx(t_rec, abs=1e-5)
    assert m["iae"] == pytest.approx(A * tau ** 2 * (1 - (1 + 8 / tau) * math.exp(-8 / tau)), rel=1e-5)


def test_control_metrics_sines_and_clipping():
    dt, n = 0.02, 2 ** 14
    t = np.arange(n) * dt
    a, b, f1, f2 = 3.0, 1.0, 0.5, 8.0  # 8 Hz above the 5 Hz cut, 0.5 Hz below
    u = a * np.sin(2 * np.pi * f1 * t) + b * np.sin(2 * np.pi * f2 * t)
    m = control_metrics(t, u, u_limit=100.0, hf_cut_hz=5.0, nperseg=1024)
    assert m["rms"] == pytest.approx(math.sqrt((a * a + b * b) / 2), rel=1e-3)
    assert m["hf_power"] == pytest.approx(b * b / 2, rel=0.02)  # sine power b^2/2, leakage < 2 %
    assert m["hf_fraction"] == pytest.approx(b * b / (a * a + b * b), rel=0.02)
    assert m["time_saturated_s"] == 0.0 and m["hf_cut_hz"] == 5.0
    # clipped sine: fraction of time at the limit L is 1 - (2/pi) asin(L/A)
    A, L = 10.0, 6.0
    uc = np.clip(A * np.sin(2 * np.pi * 0.37 * t), -L, L)
    mc = control_metrics(t, uc, u_limit=L, hf_cut_hz=5.0)
    assert mc["time_saturated_pct"] == pytest.approx(100 * (1 - 2 / math.pi * math.asin(L / A)), abs=0.3)
    assert mc["peak"] == L


def test_metrics_input_errors():
    with pytest.raises(DataError, match="same length"):
        step_metrics([0, 1, 2], [0, 1], 1.0)
    with pytest.raises(DataError, match="Nyquist"):
        control_metrics(np.arange(10) * 0.02, np.zeros(10), 1.0, hf_cut_hz=30.0)
