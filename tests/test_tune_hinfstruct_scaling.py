"""Scale invariance of the structured H-inf engine: the units it picks from the plant follow the plant's
units exactly, each block declares truthfully how its parameters carry the units of its signals, and a
problem written in other units reaches the same gamma along the same path."""

import importlib
import warnings

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.tune.blocks import PID, PID2, FixedOrderSS, StaticGain, Structure
from rotorlab.tune.hinfstruct import closed_loop, hinfstruct, relative_slope

hs = importlib.import_module("rotorlab.tune.hinfstruct")


def _random_plant(seed, n=5, nw=2, nu=2, nz=3, ny=3):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) - 2.5 * np.eye(n)
    B = rng.standard_normal((n, nw + nu))
    C = rng.standard_normal((nz + ny, n))
    D = rng.standard_normal((nz + ny, nw + nu)) * 0.1
    return ct.ss(A, B, C, D)


def _rescale(P, ny, nu, a, c):
    """Controls in units ``a`` times larger (B2, D12, D22 columns), measurements ``c`` times (C2, D21, D22 rows)."""
    nz, nw = P.noutputs - ny, P.ninputs - nu
    bs, cs = np.r_[np.ones(nw), a], np.r_[np.ones(nz), c]
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    return ct.ss(A, B * bs, cs[:, None] * C, cs[:, None] * D * bs, P.dt)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_plant_units_follow_the_plants_units_exactly(seed):
    P = _random_plant(seed)
    rng = np.random.default_rng(10 + seed)
    a, c = 10.0 ** rng.uniform(-3, 3, 2), 10.0 ** rng.uniform(-3, 3, 3)
    lgu, lgy = hs._plant_units(P, 3, 2)
    lgu2, lgy2 = hs._plant_units(_rescale(P, 3, 2, a, c), 3, 2)
    np.testing.assert_allclose(lgu2 - lgu, np.log(a), atol=1e-9)
    np.testing.assert_allclose(lgy2 - lgy, np.log(c), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_plant_in_its_own_units_is_the_same_numbers_in_any_units(seed):
    # the search runs on this plant: rescaled and normalised back it differs by round-off (up to about 1e-14
    # relative), which the rounding to SNAP_BITS removes; the gains map to the same numbers too
    P = _random_plant(seed)
    rng = np.random.default_rng(10 + seed)
    a, c = 10.0 ** rng.uniform(-3, 3, 2), 10.0 ** rng.uniform(-3, 3, 3)
    S = Structure([StaticGain(3, 2, value=rng.standard_normal((2, 3)))])
    u1 = hs._PlantUnits(S, P, 3, 2)
    K2 = (1 / a)[:, None] * S.values.reshape(2, 3) * (1 / c)[None, :]
    S2 = Structure([StaticGain(3, 2, value=K2)])
    u2 = hs._PlantUnits(S2, _rescale(P, 3, 2, a, c), 3, 2)
    for M1, M2 in zip((u1.P.A, u1.P.B, u1.P.C, u1.P.D), (u2.P.A, u2.P.B, u2.P.C, u2.P.D)):
        np.testing.assert_array_equal(M2, M1)
    np.testing.assert_array_equal(u2.inward(S2.values), u1.inward(S.values))
    np.testing.assert_array_equal(u2.sigma, u1.sigma)
    # and the normalised plant is the caller's to the rounding: |P22| about 1, nothing moved beyond 2**-24
    B = np.asarray(P.B, float) * np.r_[np.ones(2), 1 / np.exp(hs._plant_units(P, 3, 2)[0])]
    np.testing.assert_allclose(u1.P.B, B, rtol=2.0**-hs.SNAP_BITS, atol=0)
    np.testing.assert_allclose(u1.outward(u1.inward(S.values)), S.values, rtol=2.0**-hs.SNAP_BITS)


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_every_benchmark_problem_in_other_units_is_the_same_search(repo_module):
    # issue 31's matrix: every problem of benchmarks/bench_hinf_scaling.py's suite (the project's families and the
    # COMPleib problems), its controls or its measurements in units 1e-3..1e3 times larger with the controller
    # mapped back, gives hinfstruct the same plant, start, variables and start sizes bit for bit: the same seeded
    # search follows, to the same gamma (benchmarks/bench_hinf_scaling.py runs them all)
    hp = _hinf_problems()
    cl = repo_module("benchmarks/compleib.py")
    builders = dict(hp.PROBLEMS)
    builders.update({n: (lambda n=n, d=d: hp.Problem(n, *cl.plant(d), "static")) for n, d in cl.PROBLEMS.items()})
    assert len(builders) == 12
    for name, make in builders.items():
        prob = make()
        ref = None
        for side, f in [("u", 1.0)] + [(sd, f) for sd in "uy" for f in (1e-3, 1e-2, 0.1, 10.0, 100.0, 1e3)]:
            p = hp.rescaled(prob, *((f, 1.0) if side == "u" else (1.0, f)))
            S = hs._as_structure(p.controller, p.nmeas, p.ncon, 0.0)
            pr, units = hs._hinf_problem(S, p.P, p.nmeas, p.ncon, S.values, np.ones(len(S.params), bool))
            key = [np.asarray(M) for M in (units.P.A, units.P.B, units.P.C, units.P.D)]
            key += [pr.theta0, pr.scale, np.array(pr.start_decades), units.sigma]
            if ref is None:
                ref = key
                continue
            for k1, k2 in zip(key, ref):
                assert np.array_equal(k1, k2), f"{name} with {side} x{f:g}"


def test_plant_units_are_the_loop_gain_of_a_diagonal_plant():
    # P22 = diag(g1, g2)/(s + 1) over the band of its one mode: the fitted sizes multiply to g1 and g2 times the
    # mean of log|1/(jw + 1)| over 0.1..10 rad/s weighted by the open-loop |P11| = |1/(jw + 1)|, and the
    # off-diagonal zeros are left out of the fit
    g = np.array([1e-3, 50.0])
    P = ct.ss(-np.eye(2), np.hstack([np.eye(2), np.diag(g)]), np.vstack([np.eye(2), np.eye(2)]), np.zeros((4, 4)))
    lgu, lgy = hs._plant_units(P, 2, 2)
    w = hs._plant_band(-np.eye(2), 0.0)
    m = np.abs(1 / (1j * w + 1))
    gm = np.exp(np.sum(m * np.log(m)) / np.sum(m))
    np.testing.assert_allclose(np.exp(lgu + lgy), g * gm, rtol=1e-9)


@pytest.mark.parametrize("block", [
    StaticGain(3, 2, value=np.arange(6.0).reshape(2, 3) - 2.5),
    PID(2.0, 1.5, 0.3, 0.02, integral=True),
    PID2(0.35, 1.86, 0.0084, 0.043, b=0.6, c=0.3),
    FixedOrderSS(3, 2, 2, seed=4),
], ids=["static", "pid", "pid2", "fixed-order"])
def test_io_exponents_map_a_block_to_its_rescaled_twin(block):
    # ground truth: the frequency response diag(a) K(jw) diag(c) of the block with rescaled signals
    rng = np.random.default_rng(3)
    a, c = 10.0 ** rng.uniform(-2, 2, block.nu), 10.0 ** rng.uniform(-2, 2, block.ny)
    if isinstance(block, PID2):
        c[:] = c[0]  # r and y share one unit (b r - y)
    eu, ey = block.io_exponents()
    th = block.values
    th2 = th * np.exp(eu @ np.log(a) + ey @ np.log(c))
    w = np.logspace(-1, 3, 30)
    K1 = lti.freqresp(block.ss(th), w)
    K2 = lti.freqresp(block.ss(th2), w)
    np.testing.assert_allclose(K2, a[None, :, None] * K1 * c[None, None, :], rtol=1e-9, atol=1e-12)


def test_structure_io_exponents_place_each_block_on_its_signals():
    S = Structure([PID(1.0, 1.0, 0.1, 0.01, name="a"), StaticGain(2, 1, name="b")])
    eu, ey = S.io_exponents()
    assert eu.shape == (6, 2) and ey.shape == (6, 3)
    np.testing.assert_array_equal(eu[:4, 0], [1, 1, 1, 0])
    np.testing.assert_array_equal(eu[4:], [[0, 1], [0, 1]])
    np.testing.assert_array_equal(ey[4:], [[0, 1, 0], [0, 0, 1]])


def test_variable_scale_leaves_time_constants_alone():
    P = _random_plant(0, nu=1, ny=1)
    S = Structure([PID(1.0, 1.0, 0.1, 0.02)])
    free = np.ones(4, bool)
    u1 = hs._PlantUnits(S, P, 1, 1)
    u2 = hs._PlantUnits(S, _rescale(P, 1, 1, [100.0], [0.01]), 1, 1)
    np.testing.assert_allclose(u2.unit[:3], u1.unit[:3], rtol=1e-9)   # 100 * 0.01: the loop is the same
    u3 = hs._PlantUnits(S, _rescale(P, 1, 1, [1e3], [1.0]), 1, 1)
    np.testing.assert_allclose(u3.unit[:3], u1.unit[:3] / 1e3, rtol=1e-9)
    assert u3.unit[3] == u1.unit[3] == 1.0                           # tf keeps its value
    sc, _ = hs._variable_scale(u3, u3.inward(S.values), free)
    np.testing.assert_array_equal(sc[:3], 1.0)                       # gains: already in the plant's units
    assert sc[3] == pytest.approx(0.1)                               # tf: a tenth of the largest unit-free start, >= 1


@pytest.fixture(scope="module")
def ac15(repo_module):
    cl = repo_module("benchmarks/compleib.py")
    P, ny, nu = cl.plant(cl.AC15)
    return P, ny, nu, hinfstruct(P, "static", ny, nu, starts=1, hops=0)


@pytest.mark.parametrize("side,factor", [("u", 1e3), ("u", 1e-3), ("y", 1e3), ("y", 1e-2)])
def test_ac15_in_other_units_reaches_the_same_gamma_along_the_same_path(ac15, side, factor):
    # the case: AC15 with its inputs rescaled so that the optimal gain is 1000x larger went from 15.17
    # to 24.76; the engine now searches on the plant in its own units, which are the same numbers in any units
    P, ny, nu, r0 = ac15
    a, c = (factor, 1.0) if side == "u" else (1.0, factor)
    Ps = _rescale(P, ny, nu, np.full(nu, a), np.full(ny, c))
    r = hinfstruct(Ps, "static", ny, nu, starts=1, hops=0)
    # the same path: every iterate's objective equal, not only close (the descent from 2471 to 15.2)
    assert len(r0.history) >= 5 and r.history == r0.history
    assert r.gamma == pytest.approx(r0.gamma, rel=1e-12)
    # the same controller mapped back, to the round-off of the units' exponentials
    np.testing.assert_allclose(np.asarray(r.controller.D) * a * c, np.asarray(r0.controller.D), rtol=1e-12)
    # and it is right for the rescaled plant: closed loop built independently
    CL = closed_loop(Ps, ny, nu, r.controller)
    assert lti.hinfnorm(CL)[0] == pytest.approx(r.gamma, rel=1e-9)


def test_ac15_result_is_stationary_in_any_units(ac15):
    P, ny, nu, r0 = ac15
    assert r0.gamma <= 15.2 * 1.02
    assert r0.slope < 0.1
    # performance channels in other units: gamma scales, the relative stationarity does not
    nz = P.noutputs - ny
    zs = np.r_[np.full(nz, 1e-3), np.ones(ny)]
    Pz = ct.ss(P.A, P.B, zs[:, None] * np.asarray(P.C), zs[:, None] * np.asarray(P.D))
    r = hinfstruct(Pz, "static", ny, nu, starts=1, hops=0)
    # the same optimum as the published best within the margin above; the 0.5 % of issue 31 holds with AVX-512
    # kernels (15.1687 both) but not on every CPU: without them this single start ends at 15.35 (a split at one
    # accept/reject decision, docs/hinfstruct-units.md), so the bar a test can hold everywhere is this one
    assert r.gamma <= 1e-3 * 15.2 * 1.02
    assert r.slope < 0.1


def test_slope_is_the_same_number_in_any_units(ac15):
    # the reported measure at one closed loop: the same for the plant in other units of z, u and y
    P, ny, nu, r0 = ac15
    nz = P.noutputs - ny
    zs = np.r_[np.full(nz, 1e-3), np.ones(ny)]
    Pz = _rescale(ct.ss(P.A, P.B, zs[:, None] * np.asarray(P.C), zs[:, None] * np.asarray(P.D)), ny, nu,
                  np.full(nu, 1e2), np.full(ny, 1e-1))
    K = np.asarray(r0.controller.D) / (1e2 * 1e-1)
    slopes = []
    for plant, gain in ((P, np.asarray(r0.controller.D)), (Pz, K)):
        S = hs._as_structure("static", ny, nu, 0.0)
        prob, units = hs._hinf_problem(S, plant, ny, nu, gain.ravel(), np.ones(gain.size, bool))
        th = units.inward(gain.ravel())
        slopes.append(hs._slope(prob, th))
    # the measure comes from an iterative min-norm problem over the active peaks' gradients: its last digits move
    # with the SIMD kernels (1e-4 relative between AVX-512 and AVX2 here), its value does not depend on units
    assert slopes[1] == pytest.approx(slopes[0], rel=1e-3)
    # and it is not small away from the optimum: the same gains at half size
    assert hs._slope(prob, 0.5 * th) > 1.0


def test_relative_slope_is_the_relative_decrease_along_the_best_direction():
    # f(x) = max(x1, -x1) + 2 x2 near x = (0, 1): the hull of (1, 2) and (-1, 2) has its shortest vector (0, 2);
    # relative slope = 2 * |x| / f = 2 * 1 / 2 = 1; times 1e3 on f changes nothing
    G = np.array([[1.0, -1.0], [2.0, 2.0]])
    x = np.array([0.0, 1.0])
    assert relative_slope(G, x, 2.0) == pytest.approx(1.0)
    assert relative_slope(1e3 * G, x, 2e3) == pytest.approx(1.0)
    # at a kink of equal and opposite gradients the measure is zero
    assert relative_slope(np.array([[1.0, -1.0]]), np.array([3.0]), 5.0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("nnls_fails", [False, True])
def test_hull_weights_give_the_shortest_vector_even_where_nnls_stops(monkeypatch, nnls_fails):
    # scipy's nnls raises at its iteration limit (seen on COMPleib HE4 with scipy 1.18.1): the fallback must give
    # the same point. Shortest vector of the segment g1-g2, analytic: t = clip(g2.(g2-g1) / |g2-g1|^2, 0, 1)
    if nnls_fails:
        def raising(*args, **kwargs):
            raise RuntimeError("Maximum number of iterations reached.")
        monkeypatch.setattr(hs, "nnls", raising)
    rng = np.random.default_rng(3)
    for _ in range(20):
        g1, g2 = rng.standard_normal(4), rng.standard_normal(4)
        t = np.clip(g2 @ (g2 - g1) / ((g2 - g1) @ (g2 - g1)), 0.0, 1.0)
        h = hs._min_norm_hull(np.column_stack([g1, g2]))
        np.testing.assert_allclose(h, t * g1 + (1 - t) * g2, atol=1e-5 * np.linalg.norm(g1 - g2))
    # the origin inside the hull of three gradients, the third repeated: the shortest vector is zero
    G = np.array([[1.0, -1.0, 0.0, 0.0], [1.0, 1.0, -1.0, -1.0]])
    lam = hs._hull_weights(G)
    assert lam.min() >= 0.0 and lam.sum() == pytest.approx(1.0)
    assert np.linalg.norm(G @ lam) < 1e-5


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_pid_in_other_units_reaches_the_same_gamma():
    # mixed sensitivity [W1 S; W2 KS] of 1/(s + 1) with a PID whose filter constant is tuned too, with the control
    # in units 1000x larger and the measurement in units 100x smaller (kp, ki, kd start divided by 10, tf the
    # same). The optimum is flat along (kd, tf): runs that differ in round-off end 0.07 % apart at different
    # (kd, tf); in the plant's own units the two runs are the same numbers, and take the same path
    P = ct.minreal(ct.augw(ct.tf([1], [1, 1]), ct.tf([0.5, 2], [1, 0.05]), ct.tf([0.2], [1])), verbose=False)
    a, c = 1e3, 1e-2
    r0 = hinfstruct(P, PID(1.0, 0.5, 0.1, 0.05), 1, 1, starts=1, hops=0)  # one plain start in each units
    Ps = _rescale(P, 1, 1, [a], [c])
    r = hinfstruct(Ps, PID(1.0 / (a * c), 0.5 / (a * c), 0.1 / (a * c), 0.05), 1, 1, starts=1, hops=0)
    assert r.history == r0.history
    assert r.gamma == pytest.approx(r0.gamma, rel=1e-12)
    assert lti.hinfnorm(closed_loop(Ps, 1, 1, r.controller))[0] == pytest.approx(r.gamma, rel=1e-9)


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_default_options_reach_the_full_order_optimum_where_one_start_splits_off():
    # benchmarks' mixsyn3 (W1 S / W2 KS of an unstable plant, full-order controller) with its measurement in units
    # 1000x smaller: a single start can split at one accept/reject decision, on round-off alone (another number of
    # BLAS threads; other units, before the search ran on the plant's own units), into a closed-loop mode on the
    # stability margin at gamma 5.10. Ground truth: the full-order optimum from control.hinfsyn, re-verified with
    # ab13dd. The default options (several starts, then basin hopping from the best) reach it
    P = ct.minreal(ct.augw(ct.tf([1], [1, -0.5]), ct.tf([0.5, 2], [1, 0.02]), ct.tf([0.5, 0.1], [0.01, 1])),
                   verbose=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bound = lti.hinfnorm(ct.hinfsyn(P, 1, 1)[1])[0]
    c = 1e-3
    Ps = _rescale(P, 1, 1, [1.0], [c])
    S = Structure([FixedOrderSS(P.nstates, 1, 1, seed=0)])
    S.set_values(S.values * np.exp(-S.io_exponents()[1] @ np.log([c])))  # the unscaled problem's start closed loop
    r = hinfstruct(Ps, S, 1, 1)
    assert r.gamma == pytest.approx(bound, rel=5e-3)
    assert lti.hinfnorm(closed_loop(Ps, 1, 1, r.controller))[0] == pytest.approx(r.gamma, rel=1e-9)
    # the hops ran, and none of their verified results is below the optimum (hinfsyn's controller comes from a
    # bisection on gamma and is within about 0.02 % of it)
    assert r.hops and min(r.hops) >= bound * (1 - 1e-3)


def _hinf_problems():
    """benchmarks/hinf_problems.py, registered in sys.modules (its dataclass looks its module up there)."""
    import importlib.util
    import sys
    from pathlib import Path

    if "hinf_problems_bench" not in sys.modules:
        path = Path(__file__).resolve().parents[1] / "benchmarks" / "hinf_problems.py"
        spec = importlib.util.spec_from_file_location("hinf_problems_bench", path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
    return sys.modules["hinf_problems_bench"]


def _sigma(P, ny, nu):
    return hs._PlantUnits(hs._as_structure("static", ny, nu, 0.0), P, ny, nu).sigma


def test_sweep_decades_follow_the_plant_not_its_units():
    hp = _hinf_problems()
    prob = hp.flex20(0)
    dec = hs._sweep_decades(_sigma(prob.P, 2, 2))
    # flex20s0's normalised P22 crosses 1 up to loop gains of about 10^3.6: beyond the random starts' 10^3
    assert dec[0] == pytest.approx(hs.START_TOP - hs.SWEEP_BELOW)
    assert dec[1] > hs.START_TOP + 0.5
    for a, c in ((1e3, 1.0), (1.0, 1e-3), (1e-2, 10.0)):
        p2 = hp.rescaled(prob, a, c)
        assert hs._sweep_decades(_sigma(p2.P, 2, 2)) == pytest.approx(dec, rel=1e-9)
    # a plant whose plausible loop gains stay within the random starts' sizes gets no sweep by default
    P = _random_plant(0)
    assert hs._sweep_decades(_sigma(P, 3, 2)) is None
    assert hs._sweep_decades(_sigma(P, 3, 2), force=True) is not None


def test_sweep_directions_are_rank_one_on_static_gains():
    S = Structure([StaticGain(3, 2, name="K"), PID(1.0, 0.5, 0.1, 0.05, name="C")])
    n = len(S.params)
    P = _random_plant(0, nu=3, ny=4)
    prob = hs._Problem(S, [hs.Channel(P, 4, 3)], [(P, 4, 3)], np.ones(n, bool), np.ones(n))
    D = hs._sweep_directions(prob, np.random.default_rng(0), 300)
    np.testing.assert_allclose(np.sqrt(np.mean(D**2, axis=1)), 1.0, rtol=1e-12)
    sv = np.linalg.svd(D[:, :6].reshape(300, 2, 3), compute_uv=False)
    rank_one = sv[:, 1] < 1e-12 * sv[:, 0]
    np.testing.assert_array_equal(rank_one, np.arange(300) % 3 != 0)  # two in three; the others Gaussian
    np.testing.assert_array_equal(D, hs._sweep_directions(prob, np.random.default_rng(0), 300))


@pytest.mark.filterwarnings("ignore::FutureWarning")
def test_gain_scale_sweep_is_the_same_in_any_units(ac15, monkeypatch):
    # the sweep (forced on AC15, whose optimum lies within the random starts' sizes, and thinned to keep the test
    # short) draws its directions and sizes in the plant-derived variables: in other units its starts reach the
    # same gammas
    for name, value in (("SWEEP_DIRECTIONS", 60), ("SWEEP_STARTS", 2), ("SWEEP_REFINE", 1), ("SWEEP_STEP", 0.1)):
        monkeypatch.setattr(hs, name, value)
    P, ny, nu, _ = ac15
    r0 = hinfstruct(P, "static", ny, nu, starts=1, hops=0, sweep=True)
    assert len(r0.sweep) == 2 and np.all(np.isfinite(r0.sweep))
    # the starts' gammas are verified on the plant in its own units, gamma on the caller's plant (SNAP_BITS)
    assert r0.gamma == pytest.approx(min(r0.starts + r0.sweep), rel=1e-6)
    Ps = _rescale(P, ny, nu, np.full(nu, 1e3), np.full(ny, 1e-2))
    r = hinfstruct(Ps, "static", ny, nu, starts=1, hops=0, sweep=True)
    np.testing.assert_allclose(r.sweep, r0.sweep, rtol=5e-3)
    assert lti.hinfnorm(closed_loop(Ps, ny, nu, r.controller))[0] == pytest.approx(r.gamma, rel=1e-9)
