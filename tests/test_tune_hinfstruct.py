"""Structured H-inf engine against ground truth: full-order hinfsyn, a closed-form static optimum,
independent closed-loop construction, and clear errors on bad input."""

import importlib

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.executor import SerialExecutor
from rotorlab.tune.blocks import PID, PID2, Block, FixedOrderSS, StaticGain
from rotorlab.tune.hinfstruct import NotStabilisableError, StabilisationError, closed_loop, hinfstruct

# the module itself: rotorlab.tune re-exports the function hinfstruct under the module's name
hs = importlib.import_module("rotorlab.tune.hinfstruct")


@pytest.mark.parametrize("dt", [0.0, 0.02])
def test_pid_blocks_match_lti_forms(dt):
    w = np.logspace(-1, np.log10(np.pi / 0.02) - 0.01, 50)
    blk = PID2(0.35, 1.86, 0.0084, 0.043, b=0.6, c=0.3, dt=dt)
    ref = lti.pid2_ss(0.35, 1.86, 0.0084, 0.043, b=0.6, c=0.3, dt=dt)
    np.testing.assert_allclose(lti.freqresp(blk.ss(), w), lti.freqresp(ref, w), rtol=1e-9, atol=1e-12)
    one = PID(5.46, 0.0, 0.94, 0.038, dt=dt, integral=False)
    np.testing.assert_allclose(lti.freqresp(one.ss(), w), lti.freqresp(lti.pid_tf(5.46, 0, 0.94, 0.038, dt), w),
                               rtol=1e-9)


def _mixsyn_plant():
    G = ct.tf([1], [1, 1])
    W1 = ct.tf([0.5, 2], [1, 0.05])
    W2 = ct.tf([0.2], [1])
    return ct.minreal(ct.augw(G, W1, W2), verbose=False)


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_full_order_structure_reaches_hinfsyn():
    P = _mixsyn_plant()
    K, CL, gam, _ = ct.hinfsyn(P, 1, 1)
    gam_opt = lti.hinfnorm(CL)[0]
    r = hinfstruct(P, FixedOrderSS(K.nstates, 1, 1, seed=3), 1, 1, starts=2, seed=1)
    # the full-order optimum is a lower bound up to hinfsyn's own gamma-iteration tolerance, which is
    # coarser than 1e-4: the engine's controller here is 0.08 % below hinfsyn's (0.74236 vs 0.74295, the
    # closed loop's norm confirmed on a 20000-point grid up to 1e8 rad/s)
    assert r.gamma >= gam_opt * (1 - 1e-3)
    assert r.gamma <= gam_opt * 1.01


def test_static_gain_closed_form_optimum():
    # x' = a x + w + u, z = [x; rho u], y = x, u = K y. For k = -K > a: T = [1; rho K]/(s - a - K),
    # ||T||_inf = sqrt(1 + rho^2 k^2)/(k - a) (DC peak), minimised at k* = -1/(rho^2 a).
    a, rho = -1.0, 0.5
    P = ct.ss([[a]], [[1.0, 1.0]], [[1.0], [0.0], [1.0]], [[0, 0], [0, rho], [0, 0]])
    r = hinfstruct(P, "static", 1, 1, starts=1)
    k = -1 / (rho**2 * a)
    assert r.params["K.k[0,0]"] == pytest.approx(-k, rel=1e-3)
    assert r.gamma == pytest.approx(np.sqrt(1 + rho**2 * k**2) / (k - a), rel=1e-5)
    assert np.allclose(r.controller.D, [[r.params["K.k[0,0]"]]])


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_multistart_best_and_independent_verification():
    P = _mixsyn_plant()
    r = hinfstruct(P, FixedOrderSS(1, 1, 1, seed=0), 1, 1, starts=3, seed=7)
    # the starts' gammas are verified on the plant in its own units (entries rounded to SNAP_BITS), gamma on P
    assert len(r.starts) == 3 and r.gamma == pytest.approx(min(r.starts), rel=1e-6)
    # closed loop built independently: pad K to map every output of P to every input, close with feedback
    K = r.controller
    nz, nw = P.noutputs - 1, P.ninputs - 1
    Kpad = ct.ss(K.A, np.hstack([np.zeros((K.nstates, nz)), K.B]), np.vstack([np.zeros((nw, K.nstates)), K.C]),
                 np.block([[np.zeros((nw, nz)), np.zeros((nw, 1))], [np.zeros((1, nz)), K.D]]))
    CL = ct.feedback(P, Kpad, sign=1)[:nz, :nw]
    assert lti.hinfnorm(CL)[0] == pytest.approx(r.gamma, rel=1e-6)
    assert lti.hinfnorm(closed_loop(P, 1, 1, K))[0] == pytest.approx(r.gamma, rel=1e-9)
    assert r.history[-1] <= r.history[0]


def test_discrete_static_output_feedback_is_stabilising():
    P = ct.c2d(ct.ss([[0.5, 1], [0, -2]], [[1, 0], [0, 1]], [[1, 0], [1, 0]], [[0, 0], [0, 0]]), 0.05)
    r = hinfstruct(P, StaticGain(1, 1, value=[[-2.0]], dt=0.05), 1, 1)
    assert np.isfinite(r.gamma) and lti.is_stable(closed_loop(P, 1, 1, r.controller))


def test_bad_inputs_give_clear_errors():
    P = ct.ss([[-1.0]], [[1.0, 1.0]], [[1.0], [1.0]], [[0, 0], [0, 0]])
    with pytest.raises(ValueError, match="nmeas=2"):
        hinfstruct(P, "static", 2, 1)
    with pytest.raises(ValueError, match="controller has 2 inputs"):
        hinfstruct(P, StaticGain(2, 1), 1, 1)
    Pn = ct.ss([[np.nan]], [[1.0, 1.0]], [[1.0], [1.0]], [[0, 0], [0, 0]])
    with pytest.raises(ValueError, match="NaN"):
        hinfstruct(Pn, "static", 1, 1)
    # unstable mode that u cannot reach: no controller stabilises it
    Pu = ct.ss(np.diag([1.0, -1.0]), [[1.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]], np.zeros((2, 2)))
    with pytest.raises(NotStabilisableError, match="stabilis"):
        hinfstruct(Pu, "static", 1, 1)


@pytest.mark.parametrize("dt", [0.0, 0.02])
def test_pid_exact_matrix_derivatives_match_central_differences(dt):
    for blk in (PID2(0.35, 1.86, 0.0084, 0.043, b=0.6, c=0.3, dt=dt),
                PID2(5.46, 0.0, 0.94, 0.038, b=0.9, c=0.0, dt=dt, integral=False),
                PID(0.3, 1.0, 0.01, 0.05, dt=dt)):
        th = blk.values
        idx = range(len(th))
        exact = blk.matrix_derivatives(th, idx)
        numeric = Block.matrix_derivatives(blk, th, idx)
        # one (dA, dB, dC, dD) per parameter on both sides: zip alone would pass a short or empty list
        assert len(exact) == len(numeric) == len(th) and all(len(e) == len(n) == 4 for e, n in zip(exact, numeric))
        for e, n in zip(exact, numeric):
            for me, mn in zip(e, n):
                np.testing.assert_allclose(me, mn, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(mn).max()))


def test_batched_channel_gradients_match_finite_differences():
    # the batched evaluator (all channels and frequencies in one LFT) against central differences of its
    # own values, on a 2x2 channel (SVD path) and a SISO channel with a 'min' mode (vector path)

    rng = np.random.default_rng(4)
    G = ct.rss(4, 4, 4, strictly_proper=True)
    A = np.asarray(G.A) - (max(0.0, np.max(np.linalg.eigvals(G.A).real)) + 0.5) * np.eye(4)
    P = ct.ss(A, G.B, G.C, 0.1 * rng.standard_normal((4, 4)))
    chans = [hs.Channel(P, 2, 2, name="max"), hs.Channel(P[[0, 2, 3], [0, 2, 3]], 2, 2, mode="min", name="min")]
    S = hs._as_structure([FixedOrderSS(1, 2, 2, seed=2)], 2, 2, 0.0)
    th = S.values
    free = np.ones(th.size, bool)
    prob = hs._Problem(S, chans, [(P, 2, 2)], free, np.ones(th.size))
    pts = hs._Points(chans, [(0, np.array([0.3, 2.0])), (1, np.array([0.5, 1.0, 4.0]))])
    _, grads = prob.evaluate_points(th, pts, grad=True)
    assert len(grads) == 2  # one per request: the zip below would pass a short list
    for i in range(th.size):
        h = 1e-6
        tp, tm = th.copy(), th.copy()
        tp[i] += h
        tm[i] -= h
        vp, vm = prob.evaluate_points(tp, pts)[0], prob.evaluate_points(tm, pts)[0]
        for g, a, b in zip(grads, vp, vm):
            np.testing.assert_allclose(g[i], (a - b) / (2 * h), rtol=1e-5, atol=1e-7)


def _gain22_plant():
    # x1' = 20 x1 + 2 x2 + u1 + w1: no closed loop is stable unless the first loop gain beats about -20
    A = np.array([[20.0, 2.0, 0.0], [0.0, -1.0, 1.0], [-3.0, 0.0, -2.0]])
    B = np.hstack([np.eye(3), np.zeros((3, 2)), np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])])
    C = np.vstack([np.eye(3), np.zeros((2, 3)), np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])])
    D = np.zeros((7, 7))
    D[3:5, 5:7] = 0.05 * np.eye(2)
    D[5:7, 3:5] = 0.1 * np.eye(2)
    return ct.ss(A, B, C, D)


def test_stabilisation_phase_finds_a_large_gain_from_zero():
    P = _gain22_plant()
    r = hinfstruct(P, "static", 2, 2, starts=1)  # K = 0 start: spectral abscissa 20
    k11 = r.params["K.k[0,0]"]
    assert k11 < -20.0
    assert lti.is_stable(closed_loop(P, 2, 2, r.controller))
    # the x1 loop alone: z1 = x1 from w1 is 1/(s - 20 - k11) with a DC peak 1/|20 + k11| <= gamma
    assert r.gamma >= 1.0 / abs(20.0 + k11) - 1e-9


def test_not_stabilisable_only_with_a_certificate():
    # unstable mode at +1 that u cannot reach: the PBH test certifies it
    Pu = ct.ss(np.diag([1.0, -1.0]), [[1.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]], np.zeros((2, 2)))
    with pytest.raises(NotStabilisableError, match=r"1\+0j: not controllable from u \(PBH rank test\)\. The minimised spectral abscissa .* is 1 "):
        hinfstruct(Pu, "static", 1, 1)
    # double integrator with position-only static feedback: s^2 - k is never stable, yet no mode is fixed
    # (the poles move with k), so the engine must not claim a proof
    Pd = ct.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [1.0, 1.0]], [[1.0, 0.0], [1.0, 0.0]], np.zeros((2, 2)))
    with pytest.raises(StabilisationError, match="not a proof") as exc:
        hinfstruct(Pd, "static", 1, 1)
    assert not isinstance(exc.value, NotStabilisableError)


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_full_order_from_a_random_start_reaches_hinfsyn_on_an_unstable_plant():
    G = ct.tf([1], [1, -0.5])
    P = ct.minreal(ct.augw(G, ct.tf([0.5, 2], [1, 0.02]), ct.tf([0.5, 0.1], [0.01, 1])), verbose=False)
    _, CL, _, _ = ct.hinfsyn(P, 1, 1)
    gam_opt = lti.hinfnorm(CL)[0]
    r = hinfstruct(P, FixedOrderSS(P.nstates, 1, 1, seed=0), 1, 1, starts=1, seed=0)
    # lower side: hinfsyn's gamma iteration stops about 1e-4 above the optimum (the engine lands below it)
    assert gam_opt * (1 - 1e-3) <= r.gamma <= gam_opt * 1.01


def test_starts_run_through_the_executor_and_are_scaled():
    P = _gain22_plant()
    r = hinfstruct(P, "static", 2, 2, starts=3, seed=5, executor=SerialExecutor())
    assert len(r.starts) == 3 and np.all(np.isfinite(r.starts))
    r2 = hinfstruct(P, "static", 2, 2, starts=3, seed=5, n_jobs=2)
    assert r2.starts == r.starts  # same seed, same result on another executor
    # the basin-hopping rounds after the starts run through it too, with the same result
    assert r.hops and r2.hops == r.hops and r2.gamma == r.gamma


def _sof_5x2x3():
    # 5 states (one mode at +0.3), 2 controls, 3 measurements, as drawn from seed 0
    rng = np.random.default_rng(0)
    n, m, p = 5, 2, 3
    A = rng.standard_normal((n, n))
    A -= (np.max(np.linalg.eigvals(A).real) - 0.3) * np.eye(n)
    B = np.hstack([rng.standard_normal((n, 2)), np.zeros((n, p)), rng.standard_normal((n, m))])
    C = np.vstack([rng.standard_normal((2, n)), np.zeros((m, n)), rng.standard_normal((p, n))])
    D = np.zeros((2 + m + p, 2 + p + m))
    D[2:2 + m, 2 + p:] = 0.3 * np.eye(m)
    D[2 + m:, 2:2 + p] = 0.1 * np.eye(p)
    return ct.ss(A, B, C, D)


def test_descends_past_where_the_previous_engine_stopped():
    P = _sof_5x2x3()
    # where the previous trust-region SQP engine ended from K = 0 (its 60-iteration budget spent)
    K_old = np.array([[1.4916700502248326, -0.40411406675214173, 0.7123833096995359],
                      [9.242452647311087, -5.910158887567185, 3.0267501385738678]])

    def gamma(K):
        return lti.hinfnorm(closed_loop(P, 3, 2, StaticGain(3, 2, value=K).ss()))[0]

    g_old = gamma(K_old)
    assert g_old == pytest.approx(2.2643, rel=1e-4)
    # a kink (several peaks of equal height), where a plain gradient step does not descend
    r = hinfstruct(P, StaticGain(3, 2, value=K_old), 3, 2, starts=1)
    assert r.gamma < 0.97 * g_old
    assert r.stationarity < 1e-3
    assert r.gamma == pytest.approx(gamma(r.controller.D), rel=1e-9)


def test_gradient_sampling_reaches_the_minimum_of_a_max_function():
    # f(x) = max_i (a_i . x + b_i) + mu/2 |x|^2: convex, non-smooth at the minimum, where 3 of the 4 pieces are
    # active in 6 variables; its minimum is the solution of the smooth epigraph QP
    # min t + mu/2 |x|^2 s.t. a_i . x + b_i <= t (SLSQP, to 1e-12)
    rng = np.random.default_rng(3)
    n, k, mu = 6, 4, 0.1
    A, b = rng.standard_normal((k, n)), rng.standard_normal(k)

    def fg(x):
        v = A @ x + b
        i = int(np.argmax(v))
        return float(v[i] + 0.5 * mu * x @ x), A[i] + mu * x

    from scipy.optimize import minimize
    qp = minimize(lambda z: z[n] + 0.5 * mu * z[:n] @ z[:n], np.zeros(n + 1), method="SLSQP",
                  constraints=[{"type": "ineq", "fun": lambda z: z[n] - A @ z[:n] - b}],
                  options={"ftol": 1e-14, "maxiter": 500})
    f_star, x_star = qp.fun, qp.x[:n]
    x0 = rng.standard_normal(n)
    f0, g0 = fg(x0)
    # plain BFGS with weak Wolfe steps stops short at the kink; gradient sampling from there reaches f*
    x1, f1, g1 = hs._bfgs(fg, x0, f0, g0, max_iter=200, tol=1e-10, deadline=None, history=[])
    hist, radii, tol = [], (1e-2, 1e-4, 1e-6, 1e-8, 1e-10), 1e-10
    x2, f2, _ = hs._gradient_sampling(fg, x1, f1, g1, rng=np.random.default_rng(0), max_iter=500, tol=tol,
                                      deadline=None, history=hist, radii=radii)
    # How close the method gets is set by its last sampling radius, not by the arithmetic: where it stops, a
    # vector of norm <= delta = tol max(1, |f|) lies in the hull of gradients sampled within eps of x, and for a
    # convex f with Lipschitz constant L there that bounds f(x) - f* <= 2 L eps + delta |x - x*| (each sampled
    # gradient g_j at y_j gives f* >= f(y_j) + g_j . (x* - y_j) >= f(x) - 2 L eps + g_j . (x* - x)). Last-bit
    # differences (another CPU's BLAS) move the stopping point inside that bound (4.5e-9 here): 1.3e-10 above f*
    # with OpenBLAS's AVX-512 kernels, 7e-13 with its Haswell ones; BFGS stopped 9e-7 to 1.3e-6 above.
    eps = radii[-1] * max(1.0, float(np.sqrt(np.mean(x2 * x2))))
    L = np.linalg.norm(A, axis=1).max() + mu * (np.linalg.norm(x2) + eps)
    bound = 2 * L * eps + tol * max(1.0, abs(f2)) * np.linalg.norm(x2 - x_star)
    assert -1e-12 <= f2 - f_star <= bound  # SLSQP's own accuracy below f*
    assert f1 - f_star > 10 * bound  # a point short of the minimum (where BFGS stopped) fails it
    assert all(b <= a for a, b in zip(hist, hist[1:]))


def test_compleib_ac15_within_two_percent_of_the_published_static_optimum(repo_module):
    # benchmarks/compleib.py: the COMPleib matrices, published values and independent check, one source of truth
    cl = repo_module("benchmarks/compleib.py")
    P, ny, nu = cl.plant(cl.AC15)
    r = hinfstruct(P, "static", ny, nu, starts=1)
    best = min(v for _, v in cl.PUBLISHED["AC15"])  # hinfstruct's 15.2 (Guo et al. 2023 baselines)
    assert r.gamma <= 1.02 * best
    stable, g, grid = cl.verify(P, ny, nu, np.asarray(r.controller.D))
    assert stable
    assert g == pytest.approx(r.gamma, rel=1e-9)
    assert grid == pytest.approx(g, rel=1e-4)


def _bench_problems():
    """benchmarks/hinf_problems.py: the project's own hard problem families."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "hinf_problems.py"
    if "hinf_problems_bench" not in sys.modules:
        spec = importlib.util.spec_from_file_location("hinf_problems_bench", path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod  # its dataclass looks its module up there
        spec.loader.exec_module(mod)
    return sys.modules["hinf_problems_bench"]


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_stabilisation_keeps_a_start_near_its_drawn_size():
    # mimo8's 8th random start of hinfstruct(seed=0) (rms 2.8 scaled units): BFGS on the spectral abscissa
    # alone follows a high-gain direction, where the abscissa keeps falling slowly, to a stable point of rms
    # ~2600 (gamma 32.8 after the H-inf phase, 53x the best start); stabilising controllers of the start's
    # size exist, and the phase must return one
    prob_b = _bench_problems().mimo8()
    S = hs._as_structure("static", prob_b.nmeas, prob_b.ncon, 0.0)
    n = len(S.params)
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    ch = hs.Channel(prob_b.P, prob_b.nmeas, prob_b.ncon, exact_peak=True)
    prob = hs._Problem(S, [ch], [(prob_b.P, prob_b.nmeas, prob_b.ncon)], np.ones(n, bool), np.full(n, 0.1))
    rng = np.random.default_rng(0)
    th0 = [hs._scaled_start(prob, np.zeros(n), rng, lower, upper) for _ in range(7)][-1]
    size0 = np.sqrt(np.mean(prob.x_of(th0) ** 2))

    def rms(th):
        return np.sqrt(np.mean(prob.x_of(th) ** 2))

    drifted = hs._stabilise(prob, th0, lower, upper, np.random.default_rng(1), redraws=0)
    kept = hs._stabilise(prob, th0, lower, upper, np.random.default_rng(1))
    assert prob.stable(drifted) and prob.stable(kept)
    assert rms(drifted) > 300 * size0
    assert rms(kept) <= 30 * size0


def test_flex20s0_reference_gain_is_a_stationary_point_in_a_thin_stable_band():
    # the reference of the flexible-structure family's acceptance bar. Obtained by benchmarks/flex_reference.py:
    # gamma minimised on each sphere |K|_F = s (s = 1e3..1e6, rank-one angle grid 24 x 24, both signs, Nelder-Mead
    # from the three best), the best at s = 1.78e5 (51,295) polished by one hinfstruct start (starts=1, hops=0) to
    # 48,623.219; Nelder-Mead on the exact norm from it (8000 evaluations) ends at 48,623.219 too. The 50 random
    # starts of benchmarks/bench_hinfstruct.py end no lower than 53,074, the default search at 55,022: the gain
    # stabilises only between about half and twice its largest singular value, a band random starts rarely hit
    prob = _bench_problems().flex20(0)
    K = np.array([[-107020.8845274874, -62444.11006197812], [-118215.12347250902, -68761.07472166368]])

    def gamma(K):
        cl = closed_loop(prob.P, 2, 2, ct.ss([], [], [], K))
        if np.max(np.linalg.eigvals(np.asarray(cl.A, float)).real) >= 0:
            return np.inf
        return lti.hinfnorm(cl)[0]

    g = gamma(K)
    assert g == pytest.approx(48623.219, rel=1e-6)
    # a local minimum: no step of 1e-4 relative along any gain lowers gamma
    for i in range(4):
        for sign in (1.0, -1.0):
            Kp = K.copy().ravel()
            Kp[i] *= 1.0 + sign * 1e-4
            assert gamma(Kp.reshape(2, 2)) > g * (1.0 - 1e-6)
    U, sv, Vt = np.linalg.svd(K)
    assert sv[1] < 1e-3 * sv[0]  # nearly rank one
    for f in (0.5, 2.0):
        Kf = f * sv[0] * np.outer(U[:, 0], Vt[0]) + sv[1] * np.outer(U[:, 1], Vt[1])
        assert gamma(Kf) == np.inf


def _hinfstruct_problem(P, ny, nu):
    """The optimisation problem hinfstruct builds for static output feedback from K = 0, and its plant units."""
    S = hs._as_structure("static", ny, nu, 0.0)
    return hs._hinf_problem(S, P, ny, nu, S.values, np.ones(ny * nu, bool))


def test_gain_scale_sweep_reaches_flex20s0s_reference_from_its_thin_band():
    # flex20s0's best known controller (the pinned reference above: 48,623.219 at an rms size of about 1680 in the
    # plant-derived variables) lies beyond the random starts' largest size (1000 units); the sweep covers its size,
    # and there its screening, the sphere minimisation, the search over size and one start of the hybrid optimiser
    # land on it (the whole sweep, 29 sizes, is what hinfstruct runs by default on this plant)
    prob_b = _bench_problems().flex20(0)
    prob, units = _hinfstruct_problem(prob_b.P, 2, 2)
    assert prob.start_decades[1] == hs.START_TOP
    lo_dec, hi_dec = hs._sweep_decades(units.sigma)
    assert lo_dec < np.log10(1680.0) < hi_dec
    lower, upper = np.full(4, -np.inf), np.full(4, np.inf)
    rng = np.random.default_rng(hs.task_seeds(0, 3)[2])
    D = hs._sweep_directions(prob, rng, hs.SWEEP_DIRECTIONS)
    found, _ = hs._sweep_size((prob, 3.25, D, lower, upper, 1e-4))
    f, lg, x = min(found, key=lambda c: c[0])
    assert np.sqrt(np.mean(x**2)) == pytest.approx(10**3.25, rel=1e-9)  # a minimum on that size's sphere
    assert f < 52000.0  # the low-gain local minima that random starts find are 53,074-56,614
    verify = hs._Verifier(units.P, 2, 2, prob.s)
    g = verify(hs._sweep_start((prob, lg, x, lower, upper, 500, 1e-4, None, 1)))[0]
    assert g == pytest.approx(48623.219, rel=1e-3)
