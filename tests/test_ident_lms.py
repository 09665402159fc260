"""LMS impulse-response estimation and Kung's realisation against exact Markov parameters."""

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.errors import DataError
from rotorlab.ident import LMS, IdentifiedModel, kung, lms_batch, nugap
from rotorlab.lti import c2d_zoh

DT = 0.02
G = c2d_zoh(published_tf("anteos-p2a2", "testbed")[0], DT)  # P2-A2 pitch, 50 Hz


def markov(sys, n):
    A, B, C, D = (np.asarray(M, float) for M in (sys.A, sys.B, sys.C, sys.D))
    h = [D[0, 0]]
    x = B[:, 0]
    for _ in range(n - 1):
        h.append(C[0] @ x)
        x = A @ x
    return np.array(h)


def test_lms_converges_to_impulse_response_on_white_input():
    h = markov(G, 150)  # |h[149]| / max|h| ~ 1e-3: the FIR truncation is small
    u = np.random.default_rng(0).standard_normal(8000)
    y = np.convolve(u, h)[: len(u)]
    w, y_hat = lms_batch(u, y, taps=150, mu=0.5)
    assert np.linalg.norm(w - h) / np.linalg.norm(h) < 0.01
    # the a-priori error dies out as the weights converge
    assert np.std(y[-500:] - y_hat[-500:]) < 0.01 * np.std(y)


def test_lms_with_noise_and_delay_removed():
    h = markov(G, 100)
    rng = np.random.default_rng(1)
    u = rng.standard_normal(12000)
    y = np.convolve(np.r_[np.zeros(3), u[:-3]], h)[: len(u)] + 0.05 * rng.standard_normal(len(u))
    w, _ = lms_batch(u, y, taps=100, mu=0.05, delay=3)
    assert np.linalg.norm(w - h) / np.linalg.norm(h) < 0.1


def test_lms_update_matches_batch_and_does_not_allocate_weights():
    rng = np.random.default_rng(2)
    u, y = rng.standard_normal(300), rng.standard_normal(300)
    f = LMS(20, mu=0.3, leakage=1e-3)
    w_id = id(f.w)
    preds = [f.update(a, b) for a, b in zip(u, y)]
    w_batch, y_hat = lms_batch(u, y, 20, mu=0.3, leakage=1e-3)
    assert id(f.w) == w_id
    np.testing.assert_allclose(preds, y_hat)
    np.testing.assert_allclose(f.impulse_response, w_batch)


def test_kung_recovers_system_from_exact_impulse_response():
    m = kung(markov(G, 200), dt=DT)
    assert isinstance(m, IdentifiedModel) and m.method == "kung"
    assert m.order == 2  # read from the Hankel singular values
    assert m.singular_values[1] / m.singular_values[2] > 1e10
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(m.sys.A)), np.sort_complex(G.poles()), atol=1e-10)
    assert nugap(m.sys, G) < 1e-9


def test_kung_mimo_and_threshold():
    rng = np.random.default_rng(3)
    S = ct.ss(np.diag([0.9, 0.5, -0.3]), rng.standard_normal((3, 2)), rng.standard_normal((2, 3)),
              rng.standard_normal((2, 2)), 1.0)
    A, B, C, D = (np.asarray(M) for M in (S.A, S.B, S.C, S.D))
    h = np.stack([D] + [C @ np.linalg.matrix_power(A, k - 1) @ B for k in range(1, 120)])
    m = kung(h, threshold=1e-8)
    assert m.order == 3
    assert nugap(m.sys, S) < 1e-8


def test_kung_and_lms_bad_input():
    with pytest.raises(DataError, match="NaN"):
        kung(np.array([0.0, 1.0, np.nan, 0.2, 0.1]))
    with pytest.raises(DataError, match="exceeds"):
        kung(markov(G, 11), order=8)
    with pytest.raises(DataError, match="mu"):
        LMS(10, mu=0.0)


def test_too_many_taps_for_the_record_names_the_taps():
    u = np.random.default_rng(0).standard_normal(200)
    with pytest.raises(DataError, match=r"LMS with 500 taps needs at least 501 samples .* number of taps; got 200"):
        lms_batch(u, u, taps=500)
