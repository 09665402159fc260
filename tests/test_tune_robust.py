"""W_delta envelope, h_lim and Monte Carlo against known systems and the small-gain theorem."""

import functools
import math

import control as ct
import numpy as np
import pytest
import scipy.signal
from helpers import published_tf

from rotorlab import lti
from rotorlab.errors import DataError
from rotorlab.stepresponse import step_metrics
from rotorlab.tune.montecarlo import montecarlo, random_delta, single_loop, worst_case_delta
from rotorlab.tune.robust import additive_spread, control_sensitivity, fit_wdelta, h_lim, h_lim_analysis

DT = 0.02
P2A2 = published_tf("anteos-p2a2", "testbed")[0]  # P2-A2 test-bed rate model (doc 000), delay removed
W_TRUE = ct.tf(np.polymul([0.5, 0.5], [1, 4, 25]), np.polymul([1, 10], [1, 6, 100]))  # order 3, stable, min-phase


def _p2a2(dt=DT, delay=True):
    G = lti.c2d_zoh(P2A2, dt)
    return lti.with_io_delay(G, 3 * dt) if delay else G


def _pid(dt=DT):
    return lti.as_ss(lti.pid_tf(0.257, 0.643, 0.0231, 0.0225, dt))


def test_wdelta_recovers_a_known_envelope():
    # replicas G_nom +- W_true: the spread is exactly |W_true|, which the order-3 family contains
    G = P2A2
    reps = [G + W_TRUE, G - W_TRUE]
    w = np.geomspace(0.1, 300, 150)
    W = fit_wdelta(G, reps, w)
    ratio = np.abs(lti.freqresp(W, w)[:, 0, 0]) / np.abs(lti.freqresp(W_TRUE, w)[:, 0, 0])
    assert ratio.min() >= 1.0 - 1e-9
    assert ratio.max() < 1.05
    assert W.nstates == 3 and np.all(W.poles().real < 0) and np.all(ct.zeros(W).real < 0)


def test_wdelta_bounds_bootstrap_like_spread_continuous_and_discrete():
    rng = np.random.default_rng(3)
    G = P2A2
    (k, kz), (_, a1, a0) = G.num[0][0], G.den[0][0]

    def rep():
        a, b, c, d = 1 + np.array([0.05, 0.1, 0.05, 0.05]) * rng.standard_normal(4)
        return ct.tf([k * a, kz * b], [1, a1 * c, a0 * d])

    reps = [rep() for _ in range(20)]
    w = np.geomspace(0.1, 100, 120)
    W = fit_wdelta(G, reps, w)
    spread = additive_spread(G, reps, w)
    ratio = np.abs(lti.freqresp(W, w)[:, 0, 0]) / spread
    # an upper bound, and the least conservative one the order allows: about 5 % above the spread
    assert ratio.min() >= 1.0 - 1e-9 and np.median(ratio) < 1.1
    # discrete: same data sampled at 50 Hz; W_delta comes back discrete, poles/zeros inside the unit circle
    Gd, repsd = lti.c2d_zoh(G, DT), [lti.c2d_zoh(r, DT) for r in reps]
    wd = np.geomspace(0.1, 150, 120)
    Wd = fit_wdelta(Gd, repsd, wd)
    assert Wd.dt == DT
    assert np.all(np.abs(Wd.poles()) < 1) and np.all(np.abs(ct.zeros(Wd)) < 1)
    ratio = np.abs(lti.freqresp(Wd, wd)[:, 0, 0]) / additive_spread(Gd, repsd, wd)
    assert ratio.min() >= 1.0 - 1e-9 and np.median(ratio) < 1.1


def test_h_lim_analytic_single_loop():
    # G = 1/(s+1), C = k: V = -k (s+1)/(s+1+k), |V| rises to k at high frequency; W = w0 (static)
    k, w0 = 4.0, 0.3
    V = control_sensitivity(ct.tf(1, [1, 1]), ct.tf(k, 1))
    assert h_lim(ct.tf(w0, 1), V) == pytest.approx(1 / (w0 * k), rel=1e-8)
    # and with a low-pass W = w0/(s/a + 1) the peak moves: ||W V|| = w0 k max_w |(jw+1)/((jw+1+k)(jw/a+1))|
    a = 2.0
    w = np.geomspace(1e-3, 1e3, 200001)
    s = 1j * w
    peak = np.max(np.abs(w0 * k * (s + 1) / ((s + 1 + k) * (s / a + 1))))
    assert h_lim(ct.tf(w0, [1 / a, 1]), V) == pytest.approx(1 / peak, rel=1e-6)


def test_h_lim_errors():
    G, C = ct.tf(1, [1, -1]), ct.tf(0.5, 1)  # unstable plant, too little gain: closed loop unstable
    with pytest.raises(DataError, match="unstable"):
        h_lim(ct.tf(0.1, 1), control_sensitivity(G, C))
    with pytest.raises(DataError, match="NaN"):
        h_lim(ct.ss([[np.nan]], [[1]], [[1]], 0), ct.tf(1, [1, 1]))
    with pytest.raises(DataError, match="dimension"):
        control_sensitivity(ct.ss(-np.eye(2), np.eye(2), np.eye(2), 0), ct.tf(1, 1))
    with pytest.raises(DataError, match="time domain"):
        h_lim(ct.tf(1, [1, 1]), ct.tf(1, [1, 0.5], DT))
    with pytest.raises(DataError, match="order\\+1"):
        fit_wdelta(ct.tf(1, [1, 1]), [ct.tf(1.1, [1, 1])], [1.0, 2.0, 3.0])
    with pytest.raises(DataError, match="Nyquist"):
        fit_wdelta(_p2a2(), [_p2a2()], np.linspace(1, 200, 10))


def test_wdelta_bounds_the_spread_up_to_nyquist():
    # h_lim takes the norm over the whole band, so the envelope must hold at pi/dt too
    rng = np.random.default_rng(5)
    G = _p2a2(delay=False)
    (k, kz), (_, a1, a0) = P2A2.num[0][0], P2A2.den[0][0]
    reps = [lti.c2d_zoh(ct.tf([k * a, kz * b], [1, a1, a0 * c]), DT) for a, b, c in 1 + 0.05 * rng.standard_normal((10, 3))]
    w = np.geomspace(0.1, math.pi / DT, 100)
    W = fit_wdelta(G, reps, w)
    assert np.all(np.abs(lti.freqresp(W, w)[:, 0, 0]) >= additive_spread(G, reps, w) * (1 - 1e-9))


def _pi_loop(k, w_pole):
    """G = 1/(s+1) with a PI controller k (1 + 1/s) (integral action), W a low-pass 0.1/(s/w_pole + 1)."""
    G = ct.tf(1, [1, 1])
    return G, control_sensitivity(G, ct.tf([k, k], [1, 0])), ct.tf(0.1, [1 / w_pole, 1])


def test_h_lim_flags_a_controller_independent_dc_bound():
    # with a slow W the norm of W V peaks at DC, where V = -C/(1+GC) -> -1/G(0) = -1 for any PI gains:
    # h_lim = |G(0)| / |W(0)| = 10 whatever k
    for k in (0.5, 2.0):
        G, V, W = _pi_loop(k, 0.01)
        r = h_lim_analysis(W, V, G)
        assert r.h_lim == pytest.approx(10.0, rel=1e-6) and r.low_frequency_bound and r.peak_rad_s == 0.0
        assert r.v_dc_is_minus_inv_g and "controller-independent" in r.note()
    # a band-pass W (peak near 3 rad/s) moves the peak to where |V| = k |s+1| / |s+k| is large: the gains matter
    for k in (0.5, 2.0):
        G, V, _ = _pi_loop(k, 1.0)
        W = ct.tf([0.5, 0], [1, 1.8, 9])
        r = h_lim_analysis(W, V, G)
        w = np.geomspace(0.1, 100, 20001)
        mag = np.abs(lti.freqresp(W * V, w)[:, 0, 0])
        assert not r.low_frequency_bound and r.h_lim == pytest.approx(1 / mag.max(), rel=1e-6)
        assert r.peak_rad_s == pytest.approx(w[mag.argmax()], rel=0.02) and r.dc_ratio < 0.5
    # W vanishing at DC with a bump at 0.01-0.05 rad/s: the peak is not at DC (dc_ratio 0), but there |S| =
    # |s/(s+k)| <= 0.04, V = -(1 - S)/G and h_lim = |G|/|W| there to within 4 %, whatever k: still flagged
    vals = []
    for k in (0.5, 2.0):
        G, V, _ = _pi_loop(k, 1.0)
        W = ct.tf([0.1 / 0.01, 0], [1 / 0.01, 1]) * ct.tf(1, [1 / 0.05, 1])
        r = h_lim_analysis(W, V, G)
        assert r.dc_ratio < 1e-6 and 0.005 < r.peak_rad_s < 0.05 and r.sensitivity_at_peak < 0.05
        assert r.low_frequency_bound and "controller-independent" in r.note()
        vals.append(r.h_lim)
    assert vals[0] == pytest.approx(vals[1], rel=0.05)
    # ... and not where the loop gain is low: the band-pass case above has |S| near 1 at its peak
    G, V, _ = _pi_loop(2.0, 1.0)
    assert h_lim_analysis(ct.tf([0.5, 0], [1, 1.8, 9]), V, G).sensitivity_at_peak > 0.5
    # without integral action V(0) != -1/G(0)
    G = ct.tf(1, [1, 1])
    assert h_lim_analysis(ct.tf(0.1, 1), control_sensitivity(G, ct.tf(2.0, 1)), G).v_dc_is_minus_inv_g is False


@pytest.mark.parametrize("dt", [0.0, DT])
def test_worst_case_delta_is_an_allpass_that_defeats_the_loop_just_above_h_lim(dt):
    # small-gain theorem: every ||Delta|| < h_lim is stable; the phase-matched all-pass at 1.02 h_lim is not
    # continuous: the PI part of the standard inner loop with a 0.05 s roll-off (finite peak frequency)
    G, C = (_p2a2(), _pid()) if dt else (P2A2, ct.tf([0.257, 0.643], [0.05, 1, 0]))
    W = ct.tf([0.5, 1.0], [0.05, 1.0]) * 0.05
    W = lti.c2d_zoh(W, dt) if dt else W
    V = control_sensitivity(G, C)
    h = h_lim(W, V)
    for scale, unstable in ((0.98, False), (1.02, True)):
        D = worst_case_delta(W, V, scale * h)
        w = np.geomspace(0.01, math.pi / dt if dt else 1e4, 2001)
        assert np.allclose(np.abs(lti.freqresp(D, w)[:, 0, 0]), scale * h, rtol=1e-9)  # all-pass: |Delta| = h
        assert lti.is_stable(D) or D.nstates == 0
        cl = single_loop(ct.parallel(G, ct.series(D, W)), C)
        assert (lti.spectral_abscissa(cl) > 0) == unstable
    # a DC peak (integral action, slow W) is met by a static Delta = -h: the plant's DC gain G(0) - h W(0) -> 0
    G, V, W = _pi_loop(1.0, 0.01)
    D = worst_case_delta(W, V, 1.02 * h_lim(W, V))
    assert D.nstates == 0 and D.D[0, 0] == pytest.approx(-10.2)


def test_random_delta_has_exact_peak_gain():
    rng = np.random.default_rng(0)
    for dt in (0.0, DT):
        for _ in range(20):
            d = random_delta(rng, 0.7, dt)
            if d.nstates == 0:
                assert abs(d.D[0, 0]) == pytest.approx(0.7)
                continue
            num, den = scipy.signal.ss2tf(d.A, d.B, d.C, d.D)
            w = np.geomspace(1e-3, math.pi / dt if dt else 1e4, 200001)
            z = np.exp(1j * w * dt) if dt else 1j * w
            peak = np.abs(np.polyval(num[0], z) / np.polyval(den, z)).max()
            assert 0.7 * (1 - 1e-4) <= peak <= 0.7 * (1 + 1e-7)  # a grid can only under-estimate the peak
            assert lti.is_stable(d) or d.nstates == 0


def test_step_metrics_second_order():
    zeta, wn = 0.5, 2.0
    t = np.linspace(0, 20, 20001)
    _, y = ct.step_response(ct.tf(wn ** 2, [1, 2 * zeta * wn, wn ** 2]), t)
    st = step_metrics(t, y, 1.0)
    assert st["overshoot_pct"] == pytest.approx(100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2)), abs=0.05)


@pytest.fixture(scope="module")
def mc_setup():
    G, C = _p2a2(), _pid()
    W = lti.c2d_zoh(ct.tf([0.5, 1.0], [0.05, 1.0]) * 0.05, DT)
    return G, W, functools.partial(single_loop, C=C), h_lim(W, control_sensitivity(G, C))


def test_montecarlo_obeys_small_gain_theorem(mc_setup):
    G, W, builder, h = mc_setup
    inside = montecarlo(G, W, builder, 0.999 * h, n=40, seed=7, progress=False, t_final_s=2.0)
    assert inside.fraction_unstable == 0.0
    outside = montecarlo(G, W, builder, 3.0 * h, n=40, seed=7, progress=False, t_final_s=2.0)
    assert outside.fraction_unstable > 0.0


def test_montecarlo_is_reproducible_and_independent_of_n_jobs(mc_setup):
    G, W, builder, h = mc_setup
    a = montecarlo(G, W, builder, h, n=24, seed=11, progress=False, t_final_s=1.0)
    b = montecarlo(G, W, builder, h, n=24, seed=11, n_jobs=2, progress=False, t_final_s=1.0)
    assert np.array_equal(a.setpoint, b.setpoint, equal_nan=True)
    assert np.array_equal(a.load, b.load, equal_nan=True)
    c = montecarlo(G, W, builder, h, n=24, seed=12, progress=False, t_final_s=1.0)
    assert not np.array_equal(a.setpoint, c.setpoint, equal_nan=True)


def test_montecarlo_zero_uncertainty_reproduces_nominal(mc_setup):
    G, W, builder, _ = mc_setup
    r = montecarlo(G, W, builder, 0.0, n=5, seed=1, progress=False, t_final_s=2.0)
    assert np.allclose(r.setpoint, r.nominal_setpoint[None, :], atol=1e-12)
    # nominal step response against python-control's simulation of the same closed loop
    cl = builder(G)
    _, y = ct.step_response(cl[0, 0], r.t)
    assert np.allclose(r.nominal_setpoint, y, atol=1e-9)
    band = r.band("setpoint")
    assert np.all(band[0] <= band[2] + 1e-12) and np.all(band[2] <= band[-1] + 1e-12)
    assert r.setpoint_u is not None and r.summary()["fraction_unstable"] == 0.0


def test_montecarlo_reports_marginal_draws_apart():
    # DC peak: the static Delta = -h_lim puts a closed-loop pole at s = 0 (the plant loses its DC gain under
    # an integral controller): marginal, neither stable nor unstable; Delta = +h_lim is stable
    G, V, W = _pi_loop(1.0, 0.01)
    C = ct.tf([1.0, 1.0], [1, 0])
    r = montecarlo(G, W, functools.partial(single_loop, C=lti.as_ss(C)), h_lim(W, V), n=30, seed=3,
                   static_fraction=1.0, progress=False, t_final_s=1.0)
    assert 0 < r.fraction_marginal < 1 and r.fraction_unstable == 0.0
    assert np.all(np.isnan(r.setpoint[r.marginal])) and not np.any(r.stable & r.marginal)
    assert r.summary()["fraction_marginal"] == r.fraction_marginal


def test_montecarlo_bad_input(mc_setup):
    G, W, builder, _ = mc_setup
    with pytest.raises(DataError, match="time domain"):
        montecarlo(G, ct.tf(1, [1, 1]), builder, 0.1, n=2, progress=False)
    with pytest.raises(DataError, match="h must be"):
        montecarlo(G, W, builder, float("nan"), n=2, progress=False)
