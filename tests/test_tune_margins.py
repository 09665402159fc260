"""Margins against analytic loops and against python-control's frequency-response method."""

import math

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab import lti
from rotorlab.errors import DataError
from rotorlab.tune.margins import crossover_frequencies, disk_margin, margins


@pytest.mark.parametrize("k, T", [(2.0, 0.1), (5.0, 0.06), (0.5, 1.0)])
def test_integrator_with_delay_matches_analytic(k, T):
    # L = k e^{-sT}/s: |L| = k/w, phase = -90 deg - w T
    m = margins(ct.tf(k, [1, 0]), delay_s=T)
    assert m.w_gc_rad_s == pytest.approx(k, rel=1e-9)
    assert m.pm_deg == pytest.approx(90.0 - math.degrees(k * T), abs=1e-7)
    assert m.w_pc_rad_s == pytest.approx(math.pi / (2 * T), rel=1e-9)
    assert m.gm_db == pytest.approx(20 * math.log10(math.pi / (2 * T * k)), abs=1e-7)
    assert m.dm_s == pytest.approx((math.pi / 2 - k * T) / k, rel=1e-8)


@pytest.mark.parametrize("n, k", [(0, 10.0), (3, 5.0), (5, 2.0)])
def test_discrete_delay_loop_matches_analytic(n, k):
    # L = k dt/(z-1) z^-n: |L| = k dt / (2 sin(w dt/2)), phase = -(pi/2 + w dt/2) - n w dt
    dt = 0.02
    L = ct.tf([k * dt], [1, -1], dt) * lti.delay_ss(n, dt) if n else ct.tf([k * dt], [1, -1], dt)
    m = margins(L)
    wg = 2 / dt * math.asin(k * dt / 2)
    wp = math.pi / ((2 * n + 1) * dt)
    assert m.w_gc_rad_s == pytest.approx(wg, rel=1e-9)
    assert m.pm_deg == pytest.approx(90.0 - math.degrees((n + 0.5) * wg * dt), abs=1e-7)
    assert m.w_pc_rad_s == pytest.approx(wp, rel=1e-9)
    assert m.gm_db == pytest.approx(20 * math.log10(2 * math.sin(wp * dt / 2) / (k * dt)), abs=1e-7)
    assert m.dm_s == pytest.approx(math.radians(m.pm_deg) / wg, rel=1e-9)


def _p2a2_inner_loop(dt=0.02):
    """ANTEOS P2-A2 rate loop (ref. 000): PBSID test-bed model, 3-sample delay, standard PID."""
    G = lti.c2d_zoh(published_tf("anteos-p2a2", "testbed")[0], dt)
    C = lti.pid_tf(0.257, 0.643, 0.0231, 0.0225, dt)
    return ct.series(lti.as_ss(C), lti.with_io_delay(G, 3 * dt))


@pytest.mark.parametrize("make", [
    _p2a2_inner_loop,
    lambda: ct.tf([40.0], [1, 6, 11, 6]),
    lambda: ct.tf([2.0, 1.0], [1, 3, 0]) * ct.tf([1], [0.05, 1]),
])
def test_agrees_with_python_control(make):
    # python-control's 'frd' method (its most reliable on discrete loops) only handles discrete systems here
    L = make()
    m = margins(L)
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(L, method="frd" if L.dt else "best")
    assert m.gm_db == pytest.approx(20 * math.log10(gm), abs=1e-4)
    assert m.pm_deg == pytest.approx(pm, abs=1e-4)
    for mine, theirs in ((m.w_pc_rad_s, wpc), (m.w_gc_rad_s, wgc)):
        assert (math.isnan(mine) and math.isnan(theirs)) or mine == pytest.approx(theirs, rel=1e-5)


def test_disk_margin_of_pure_integrator_is_infinite_gain_and_90_deg():
    # L = k/s: S - 1/2 = (s - k)/(2 (s + k)) is all-pass with gain 1/2, so alpha = 2
    m = margins(ct.tf(3.0, [1, 0]))
    assert m.disk_alpha == pytest.approx(2.0, rel=1e-8)
    assert m.disk_pm_deg == pytest.approx(90.0)
    assert m.disk_gm_db[1] == math.inf


def test_disk_margin_matches_python_control_and_bounds_classical_margins():
    L = _p2a2_inner_loop()
    m = margins(L)
    w = np.linspace(0.01, math.pi / 0.02, 4000)
    dm, dgm, dpm = ct.disk_margins(L, w, skew=0.0)  # gridded, so it can only over-estimate alpha
    assert m.disk_alpha == pytest.approx(dm, rel=2e-3) and m.disk_alpha <= dm * (1 + 1e-9)
    assert m.disk_pm_deg == pytest.approx(dpm, rel=2e-3)
    assert m.disk_gm_db[1] == pytest.approx(dgm, rel=2e-3)
    # the disk covers a subset of the classical one-at-a-time variations
    assert m.disk_pm_deg <= m.pm_deg + 1e-9
    assert m.disk_gm_db[1] <= m.gm_db + 1e-9
    # symmetric disk: alpha = 2 / ||S - T||_inf, checked on the grid
    resp = ct.frequency_response(L, w).complex
    assert m.disk_alpha == pytest.approx(2 / np.max(np.abs((1 - resp) / (1 + resp))), rel=1e-3)


def test_disk_margin_with_exact_delay_on_grid():
    k, T = 2.0, 0.1
    alpha, _ = disk_margin(ct.tf(k, [1, 0]), delay_s=T)
    w = np.geomspace(1e-3, 1e3, 200000)
    L = k * np.exp(-1j * w * T) / (1j * w)
    assert alpha == pytest.approx(1 / np.max(np.abs(1 / (1 + L) - 0.5)), rel=1e-6)


def test_unstable_loop_has_zero_disk_margin_and_negative_gain_margin():
    L = ct.tf([40.0], [1, 6, 11, 6]) * 2.0  # 80/((s+1)(s+2)(s+3)) is closed-loop unstable (needs k < 60)
    m = margins(L)
    assert not m.stable and m.disk_alpha == 0.0
    assert m.gm_db == pytest.approx(20 * math.log10(60 / 80), abs=1e-8)


def test_all_crossovers_found():
    # resonant loop with three gain crossovers
    L = ct.tf([1.0], [1, 0]) * ct.tf([400.0], [1, 0.4, 400]) * 3.0
    wc = crossover_frequencies(L)
    w = np.geomspace(1e-2, 1e4, 400000)
    s = 1j * w
    mag = np.abs(1200.0 / (s * (s * s + 0.4 * s + 400)))
    changes = np.count_nonzero(np.diff(np.sign(mag - 1)))
    assert wc.size == changes == 3
    assert np.allclose(np.abs(lti.freqresp(L, wc)[:, 0, 0]), 1.0, atol=1e-10)
    assert margins(L).w_gc_all.size == 3


def test_bad_input():
    with pytest.raises(DataError, match="SISO"):
        margins(ct.ss(-np.eye(2), np.eye(2), np.eye(2), 0))
    with pytest.raises(DataError, match="NaN"):
        margins(ct.ss([[np.nan]], [[1]], [[1]], 0))
    with pytest.raises(DataError, match="Nyquist"):
        margins(ct.tf([0.1], [1, -1], 0.02), w=np.linspace(1, 500, 100))
    with pytest.raises(DataError, match="delay_s"):
        margins(ct.tf(1, [1, 0]), delay_s=-1.0)
