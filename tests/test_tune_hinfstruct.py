"""Structured H-inf engine against ground truth: full-order hinfsyn, a closed-form static optimum,
independent closed-loop construction, and clear errors on bad input."""

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.tune.blocks import PID, PID2, FixedOrderSS, StaticGain
from rotorlab.tune.hinfstruct import NotStabilisableError, closed_loop, hinfstruct


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
    # the full-order optimum is a lower bound (up to hinfsyn's own gamma-iteration tolerance)
    assert r.gamma >= gam_opt * (1 - 1e-4)
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
    assert len(r.starts) == 3 and r.gamma == min(r.starts)
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
    from rotorlab.tune.blocks import Block

    for blk in (PID2(0.35, 1.86, 0.0084, 0.043, b=0.6, c=0.3, dt=dt),
                PID2(5.46, 0.0, 0.94, 0.038, b=0.9, c=0.0, dt=dt, integral=False),
                PID(0.3, 1.0, 0.01, 0.05, dt=dt)):
        th = blk.values
        idx = range(len(th))
        exact = blk.matrix_derivatives(th, idx)
        numeric = Block.matrix_derivatives(blk, th, idx)
        for e, n in zip(exact, numeric):
            for me, mn in zip(e, n):
                np.testing.assert_allclose(me, mn, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(mn).max()))


def test_batched_channel_gradients_match_finite_differences():
    # the batched evaluator (all channels and frequencies in one LFT) against central differences of its
    # own values, on a 2x2 channel (SVD path) and a SISO channel with a 'min' mode (vector path)
    import importlib

    hs = importlib.import_module("rotorlab.tune.hinfstruct")
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
    for i in range(th.size):
        h = 1e-6
        tp, tm = th.copy(), th.copy()
        tp[i] += h
        tm[i] -= h
        vp, vm = prob.evaluate_points(tp, pts)[0], prob.evaluate_points(tm, pts)[0]
        for g, a, b in zip(grads, vp, vm):
            np.testing.assert_allclose(g[i], (a - b) / (2 * h), rtol=1e-5, atol=1e-7)
