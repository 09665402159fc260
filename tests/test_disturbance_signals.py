"""Disturbance signal generators: Dryden statistics (gust velocities and gradients) against MIL-F-8785C
formulas, 1-cosine gust shape, recirculation band and RMS."""

import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import quad

from rotorlab.errors import ConfigError
from rotorlab.sim.disturbances import (
    DrydenTurbulence,
    RecirculationTorque,
    dryden_psd_rates,
    dryden_psd_u,
    dryden_psd_v,
    low_altitude_scales,
    one_minus_cosine,
)

DT = 0.02
N = 2 ** 18  # 5243 s at 50 Hz


def test_low_altitude_scales_match_the_standard():
    # h = 100 ft, W20 = 30 kt written in the standard's units, compared in SI
    h_ft, w20 = 100.0, 15.0
    sig, L = low_altitude_scales(h_ft * 0.3048, w20)
    k = 0.177 + 0.000823 * h_ft
    assert L[2] == pytest.approx(h_ft * 0.3048)
    assert L[0] == L[1] == pytest.approx(h_ft / k ** 1.2 * 0.3048)
    assert sig[2] == pytest.approx(0.1 * w20)
    assert sig[0] == sig[1] == pytest.approx(0.1 * w20 / k ** 0.4)


@pytest.mark.parametrize("psd", [dryden_psd_u, dryden_psd_v])
def test_psd_formulas_integrate_to_sigma_squared(psd):
    sigma, L, V = 1.7, 30.0, 5.0
    total = quad(lambda w: psd(w, sigma, L, V), 0, np.inf, limit=200)[0]
    assert total == pytest.approx(sigma ** 2, rel=1e-8)


def _aliased_one_sided_psd_per_hz(d, f, fs, kmax=400):
    """PSD of the sampled process: the continuous two-sided PSD (pi Phi(2 pi |f|) per Hz) folded at fs."""
    k = np.arange(-kmax, kmax + 1)[:, None]
    fk = np.abs(f[None, :] + k * fs)
    return np.stack([2 * np.pi * np.sum(d.psd(2 * np.pi * fk[:, i])[:, :], axis=0) for i in range(f.size)])


def test_dryden_variance_and_autocorrelation():
    # short length scales: many correlation times in the record, so the estimates are tight
    d = DrydenTurbulence(10.0, 30.0, sigma_mps=[1.0, 2.0, 0.5], length_scales_m=[5.0, 5.0, 3.0], seed=3)
    x = d.generate(N, DT)
    T = d.length_scales_m / d.V_mps
    # relative s.d. of a variance estimate ~ sqrt(2 int rho^2 / T_record) <= sqrt(2 T / T_record) (~2 %)
    tol = 4.0 * np.sqrt(2.0 * T / (N * DT))
    np.testing.assert_allclose(x.var(axis=0) / d.sigma_mps ** 2, 1.0, atol=np.max(tol))
    # autocorrelations: u exp(-tau/T); v, w (1 - tau / (2 T)) exp(-tau/T) (MIL-F-8785C Dryden correlations)
    for lag_s in (0.2, 0.5, 1.0):
        k = int(round(lag_s / DT))
        rho = np.array([np.mean(x[:-k, j] * x[k:, j]) / np.mean(x[:, j] ** 2) for j in range(3)])
        expect = np.array([math.exp(-lag_s / T[0]),
                           (1 - lag_s / (2 * T[1])) * math.exp(-lag_s / T[1]),
                           (1 - lag_s / (2 * T[2])) * math.exp(-lag_s / T[2])])
        np.testing.assert_allclose(rho, expect, atol=0.03)


def _assert_band_means_near_one(ratio, nseg: int, n_edges: int, bias: float = 0.0):
    """Welch-to-formula PSD ratios (bins x components) averaged over log-spaced bands of >= 32 bins are 1 within
    4 sigma (+ ``bias``): ~2 N / nseg Hann segments (50 % overlap) give a per-bin relative s.d. of
    sqrt(1.06 nseg / (2 N)), and adjacent Hann bins correlate (count half of them)."""
    per_bin = math.sqrt(1.06 * nseg / (2 * N))
    edges = np.unique(np.geomspace(1, ratio.shape[0], n_edges).astype(int))
    edges[0] = 0
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi - lo >= 32:
            np.testing.assert_allclose(ratio[lo:hi].mean(axis=0), 1.0, atol=bias + 4 * per_bin / math.sqrt((hi - lo) / 2))


def test_dryden_welch_psd_matches_formula():
    d = DrydenTurbulence(12.0, 20.0, wind20_mps=8.0, seed=11)  # standard scales at 20 m
    x = d.generate(N, DT)
    nseg = 2048
    f, pxx = signal.welch(x, fs=1 / DT, nperseg=nseg, axis=0)
    sel = slice(4, None)  # the first bins are biased by the window's resolution on the steep low end
    ratio = pxx[sel] / _aliased_one_sided_psd_per_hz(d, f[sel], 1 / DT)
    _assert_band_means_near_one(ratio, nseg, n_edges=9)
    # and the bulk of the spectrum: the median ratio over all bins is within 2 %
    np.testing.assert_allclose(np.median(ratio, axis=0), 1.0, atol=0.02)


def test_gust_gradient_psds_match_the_standard():
    # hover-like: slow advection over a quadrotor's span (the P2-A2's 1.37 m at 2.5 m/s, 5 m up)
    d = DrydenTurbulence(2.5, 5.0, seed=5)
    _, rot = d.generate_with_rates(N, DT, 1.37)
    nseg = 4096
    f, pxx = signal.welch(rot, fs=1 / DT, nperseg=nseg, axis=0)
    # the formulas per Hz, two-sided folded to one-sided: 2 pi Phi(2 pi f); up to 5 Hz, where the record's
    # sampling (Tustin gradients, aliasing of the 1/omega^2 tails) moves the PSD by < 3 %
    sel = (f >= 8 / (nseg * DT)) & (f <= 5.0)
    ratio = pxx[sel] / (2 * np.pi * d.psd_rates(2 * np.pi * f[sel], 1.37))
    _assert_band_means_near_one(ratio, nseg, n_edges=7, bias=0.03)
    # the standard's own numbers at one frequency: Phi_q(3 rad/s) for sigma_w, L_w at 5 m, b = 1.37 m, V = 2.5 m/s
    sig, L = d.sigma_mps, d.length_scales_m
    x = L[2] * 3.0 / 2.5
    phi_w = sig[2] ** 2 * L[2] / (np.pi * 2.5) * (1 + 3 * x * x) / (1 + x * x) ** 2
    assert dryden_psd_rates([3.0], sig, L, 2.5, 1.37)[0, 1] == pytest.approx(
        (3.0 / 2.5) ** 2 / (1 + (4 * 1.37 * 3.0 / (np.pi * 2.5)) ** 2) * phi_w, rel=1e-12)


def test_air_rotation_is_the_frozen_fields_rigid_rotation():
    """Air advected along +u: the field at x = +dx is the one that passed the origin dx / V earlier, so the
    rigid rotation about v is -dw/dx and about w is +dv/dx. The span filter keeps the sign and the low-frequency
    size (correlation near 1 with the finite difference seen through the same filter's low-pass part)."""
    V, b = 2.5, 1.37
    d = DrydenTurbulence(V, 5.0, seed=4)
    uvw, rot = d.generate_with_rates(20000, DT, b)
    dx = V * DT  # one sample of advection
    grad = (uvw[:-1] - uvw[1:]) / dx  # d/dx of the frozen field, per component
    for j, src, sign, Tg in ((1, 2, -1.0, 4 * b / (np.pi * V)), (2, 1, +1.0, 3 * b / (np.pi * V))):
        num, den, _ = signal.cont2discrete(([1.0], [Tg, 1.0]), DT, method="bilinear")
        ref = signal.lfilter(num.ravel(), den, sign * grad[:, src])
        c = np.corrcoef(ref[500:], rot[501:, j])[0, 1]
        assert c > 0.98, (j, c)


def test_gust_gradients_leave_the_velocity_record_as_it_was():
    a = DrydenTurbulence(2.5, 5.0, seed=9).generate(500, DT)
    b, _ = DrydenTurbulence(2.5, 5.0, seed=9).generate_with_rates(500, DT, 1.0)
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ConfigError, match="span_m"):
        DrydenTurbulence(2.5, 5.0, seed=9).generate_with_rates(500, DT, 0.0)


def test_dryden_is_seeded_and_needs_airspeed():
    a = DrydenTurbulence(5.0, 10.0, seed=7).generate(100, DT)
    b = DrydenTurbulence(5.0, 10.0, seed=7).generate(100, DT)
    c = DrydenTurbulence(5.0, 10.0, rng=np.random.default_rng(8)).generate(100, DT)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    with pytest.raises(ConfigError, match="V_mps"):
        DrydenTurbulence(0.0, 10.0)


def test_one_minus_cosine_shape():
    t0, dur, amp = 1.0, 0.8, 4.0
    t = np.arange(0.0, 3.0, 1e-4)
    v = one_minus_cosine(t, t0, dur, amp)
    assert np.all(v[(t < t0) | (t > t0 + dur)] == 0.0)
    assert np.max(v) == pytest.approx(amp) and t[np.argmax(v)] == pytest.approx(t0 + dur / 2, abs=1e-4)
    assert np.all(v >= 0.0)
    # C1: value and slope continuous at the edges (the one-sided slopes there tend to zero)
    dv = np.diff(v) / 1e-4
    assert np.max(np.abs(np.diff(dv))) < 1e-3 * np.max(np.abs(dv)) * 10
    k_edge = np.searchsorted(t, t0)
    assert abs(dv[k_edge]) < 1e-3 * np.max(np.abs(dv))
    # direction: normalised 3-vector
    v3 = one_minus_cosine(t, t0, dur, amp, direction=[3.0, 0.0, 4.0])
    np.testing.assert_allclose(v3[np.argmax(v)], [0.6 * amp, 0.0, 0.8 * amp], rtol=1e-7)


def test_recirculation_rms_and_band():
    rec = RecirculationTorque(rms_Nm=[0.2, 0.3, 0.05], cutoff_hz=1.5, seed=5)
    x = rec.generate(N, DT)
    # RMS: correlation time ~ 1 / (2 cutoff) s, so the estimate is good to ~1 %
    np.testing.assert_allclose(np.sqrt(np.mean(x ** 2, axis=0)) / rec.rms_Nm, 1.0, atol=0.03)
    f, pxx = signal.welch(x, fs=1 / DT, nperseg=1024, axis=0)
    frac_below_2hz = np.sum(pxx[f <= 2.0], axis=0) / np.sum(pxx, axis=0)
    assert np.all(frac_below_2hz > 0.95)
    # the PSD follows the Butterworth magnitude squared (4th order: -3 dB at the corner)
    w, h = signal.sosfreqz(rec.filter_sos(DT), worN=f, fs=1 / DT)
    k = np.argmin(np.abs(f - 1.5))
    assert pxx[k, 0] / pxx[2, 0] == pytest.approx(abs(h[k]) ** 2 / abs(h[2]) ** 2, rel=0.25)
