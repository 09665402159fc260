"""Excitation signals: PRBS hold statistics, the published campaign, sweeps and pulse trains, band check."""

import numpy as np
import pytest

from rotorlab.errors import ConfigError
from rotorlab.excitation import (
    ANTEOS_CAMPAIGN,
    anteos_segments,
    band_fraction,
    campaign,
    design_campaign,
    doublet,
    multistep_3211,
    prbs,
    prbs_psd,
    spectrum_check,
    sweep,
)
from rotorlab.pipeline.stages.experiments import excitation_check
from rotorlab.vehicles import load_vehicle

DT = 0.02


def _holds(u):
    edges = np.flatnonzero(np.diff(u) != 0) + 1
    return np.diff(edges)  # complete holds only (first and last may be cut)


def test_prbs_levels_and_hold_times():
    u = prbs(20000, DT, hold_range_s=(0.1, 0.2), amplitude=9.0, seed=1)
    assert set(np.unique(u)) == {-9.0, 9.0}
    h = _holds(u) * DT
    assert h.min() >= 0.1 - 1e-9 and h.max() <= 0.2 + 1e-9
    # uniform on 0.1..0.2 s quantised to 20 ms: mean 0.15 s
    assert abs(h.mean() - 0.15) < 0.005
    assert np.all(np.diff(np.sign(u[np.r_[0, np.flatnonzero(np.diff(u)) + 1]])) != 0)  # levels alternate


def test_prbs_seeded_and_duration():
    a = prbs(dt=DT, duration_s=10.0, seed=3)
    b = prbs(dt=DT, duration_s=10.0, rng=np.random.default_rng(3))
    assert len(a) == 500 and np.array_equal(a, b)
    assert not np.array_equal(a, prbs(dt=DT, duration_s=10.0, seed=4))


def test_campaign_concatenates_segments():
    segs = anteos_segments(duration_s=20.0)
    assert [s[1] for s in segs] == list(ANTEOS_CAMPAIGN["amplitudes_pct"])
    u, bounds = campaign(segs, DT, seed=0)
    assert list(bounds) == [0, 1000, 2000, 3000] and len(u) == 3000
    for (_hold, amp, _), a, b in zip(segs, bounds[:-1], bounds[1:]):
        assert set(np.unique(u[a:b])) == {-amp, amp}


def test_published_prbs_excites_4_to_8_rad_s():
    u, _ = campaign([((0.05, 0.1), 7.0, 60.0), ((0.1, 0.2), 7.0, 60.0), ((0.2, 0.4), 7.0, 60.0)], DT, seed=5)
    chk = spectrum_check(u, DT, band_rad_s=(4.0, 8.0))
    assert chk.excited  # band PSD nowhere 20 dB below the peak
    # a slow square wave (period 8 s, harmonics at 0.785, 2.36, 3.93, 5.50, ... rad/s) leaves gaps
    slow = np.sign(np.sin(2 * np.pi * np.arange(9000) * DT / 8.0))
    assert not spectrum_check(slow, DT, band_rad_s=(4.0, 8.0)).excited


def test_band_fraction_of_a_sine():
    t = np.arange(20000) * DT
    assert spectrum_check(np.sin(6.0 * t), DT, (4.0, 8.0)).band_fraction > 0.95
    assert spectrum_check(np.sin(20.0 * t), DT, (4.0, 8.0)).band_fraction < 0.01


def test_sweep_instantaneous_frequency():
    dt = 0.001
    u = sweep(20.0, dt, 0.5, 5.0)
    z = np.flatnonzero(np.diff(np.signbit(u)))
    # one period between every other zero crossing; a log sweep has f(t) = f0 (f1/f0)^(t/T)
    for a, b in ((z[0], z[2]), (z[-3], z[-1])):
        f_meas = 1.0 / ((b - a) * dt)
        f_true = 0.5 * 10 ** (0.5 * (a + b) * dt / 20.0)
        assert abs(f_meas / f_true - 1) < 0.02


def test_doublet_and_3211():
    d = doublet(0.1, 0.5, 2.0, start_s=1.0, duration_s=3.0)
    assert d[10:15].tolist() == [2.0] * 5 and d[15:20].tolist() == [-2.0] * 5 and not d[20:].any()
    m = multistep_3211(0.1, 0.2, 1.0)
    assert m.tolist()[:14] == [1.0] * 6 + [-1.0] * 4 + [1.0] * 2 + [-1.0] * 2
    assert abs(m.sum()) == 2.0


def test_bad_arguments():
    with pytest.raises(ConfigError, match="hold_range_s"):
        prbs(100, DT, hold_range_s=(0.2, 0.1))
    with pytest.raises(ConfigError, match="exactly one"):
        prbs(100, DT, duration_s=2.0)
    with pytest.raises(ConfigError, match="Nyquist"):
        spectrum_check(np.ones(100), DT, (4.0, 400.0))
    with pytest.raises(ConfigError, match="segments\\[0\\]"):
        campaign([(0.1, 7.0)], DT)


@pytest.mark.parametrize("hold", ANTEOS_CAMPAIGN["hold_ranges_s"])
def test_prbs_psd_matches_a_long_realisation(hold):
    # the exact ensemble spectrum against Welch's estimate of 20 000 s of signal; it integrates to A^2
    amp = 9.0
    u = prbs(1_000_000, DT, hold_range_s=hold, amplitude=amp, seed=2)
    chk = spectrum_check(u, DT, (0.5, 150.0), nperseg=2048)
    S = prbs_psd(chk.w_rad_s, DT, hold, amp)
    w = np.linspace(0.0, np.pi / DT, 20001)
    assert np.trapezoid(prbs_psd(w, DT, hold, amp), w) == pytest.approx(amp ** 2, rel=1e-4)
    strong = S > 0.05 * S.max()  # where the estimate's relative error is small
    assert np.median(np.abs(chk.psd[strong] / S[strong] - 1)) < 0.05
    for band in ((4.0, 8.0), (3.0, 7.0)):
        assert spectrum_check(u, DT, band, nperseg=2048).band_fraction == pytest.approx(
            band_fraction(band, DT, hold), abs=0.02)  # Welch leakage at 0.15 rad/s resolution


def test_hold_range_sets_the_excited_band():
    # a hold near T puts the power near pi/T: the 0.4-0.8 s range carries most of its power into 4-8 rad/s,
    # the shorter ranges almost none
    fr = [band_fraction((4.0, 8.0), DT, h) for h in ANTEOS_CAMPAIGN["hold_ranges_s"]]
    assert fr[3] > 0.6 and max(fr[:3]) < 0.1
    assert band_fraction((8.0, 30.0), DT, (0.1, 0.2)) > 0.7


def test_design_campaign_concentrates_power_in_the_band():
    for band in ((4.0, 8.0), (3.0, 7.0)):  # P2-A2, A2-MINI/B (ref. 000)
        d = design_campaign(band)
        assert d.holds == (3, 3, 3) and d.amplitudes_pct == (7.0, 9.0, 11.0) and d.band_fraction > 0.6
        u, _ = campaign([(ANTEOS_CAMPAIGN["hold_ranges_s"][h], a, 60.0) for h, a in zip(d.holds, d.amplitudes_pct)],
                        DT, seed=1)
        assert spectrum_check(u, DT, band).band_fraction > 0.5
    # each range is the design for a band around its own pi / mean hold
    for i, (lo, hi) in enumerate(ANTEOS_CAMPAIGN["hold_ranges_s"]):
        wc = np.pi / (0.5 * (lo + hi))
        assert design_campaign((0.7 * wc, 1.4 * wc)).holds == (i, i, i)
    with pytest.raises(ConfigError, match="amplitude"):
        design_campaign((4.0, 8.0), n_segments=4)


def test_experiments_stage_says_when_the_band_is_missed():
    spec = load_vehicle("anteos-p2a2")
    fast = prbs(dt=DT, duration_s=120.0, hold_range_s=(0.1, 0.2), amplitude=9.0, seed=0)  # power near 20 rad/s
    chk = excitation_check(fast, spec)
    assert chk["band_rad_s"] == [4.0, 8.0] and chk["band_fraction"] < 0.3 and "4-8 rad/s" in chk["warning"]
    slow = prbs(dt=DT, duration_s=120.0, hold_range_s=(0.4, 0.8), amplitude=9.0, seed=0)
    assert excitation_check(slow, spec)["warning"] is None
