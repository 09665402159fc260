"""Parametric bootstrap (Bittanti & Lovera): coverage of the true response, reproducibility across workers."""

import functools

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.errors import DataError
from rotorlab.excitation import prbs
from rotorlab.ident import IdentifiedModel, bootstrap, model_frf, moesp, pbsid
from rotorlab.lti import c2d_zoh

DT = 0.02
TRUTH = IdentifiedModel(c2d_zoh(published_tf("anteos-p2a2", "testbed")[0], DT), delay=3)


def _record(seed):
    """Innovation-form data, the setting the bootstrap and PBSID assume: ``x+ = A x + B u + K e``, with ``K``
    placing the predictor poles at 0.5 and 0.6 so that a past window of 20 captures the predictor."""
    u = prbs(3000, DT, hold_range_s=(0.05, 0.8), amplitude=7.0, seed=seed)
    A, C = np.asarray(TRUTH.sys.A), np.asarray(TRUTH.sys.C)
    K = ct.place(A.T, C.T, [0.5, 0.6]).T
    y0 = TRUTH.simulate(u)[:, 0]
    e = 0.1 * y0.std() * np.random.default_rng(seed + 1).standard_normal(len(y0))
    noise = IdentifiedModel(ct.ss(A, K, C, [[1.0]], DT)).simulate(e)[:, 0]
    return u, y0 + noise


@pytest.fixture(scope="module")
def record():
    return _record(7)


IDENT = functools.partial(pbsid, order=2, past=20, future=10, delay=3, dt=DT)


def test_band_covers_the_true_response():
    """Pointwise 95 % bands, averaged over independent records: one record's band misses the truth over
    contiguous stretches (neighbouring frequencies are strongly correlated), so coverage is a property of
    the procedure, checked over six experiments of 200 replications each (measured: 0.94 magnitude, 1.0
    phase; the bound leaves room for the sampling error of six experiments)."""
    w = np.logspace(-1, np.log10(0.9 * np.pi / DT), 80)
    G = model_frf(TRUTH.sys, w)[:, 0, 0]
    cover_mag, cover_ph = [], []
    for seed in range(7, 13):
        u, y = _record(seed)
        res = bootstrap(u, y, IDENT, n_boot=200, seed=seed, progress=False)
        assert len(res.models) == 200 and res.nominal.method == "pbsid"
        b = res.band(w, level=0.95)
        cover_mag.append(np.mean((np.abs(G) >= b["mag_lo"][:, 0, 0]) & (np.abs(G) <= b["mag_hi"][:, 0, 0])))
        ph = np.unwrap(np.angle(G))
        ph += 2 * np.pi * np.round((b["phase"][0, 0, 0] - ph[0]) / (2 * np.pi))
        cover_ph.append(np.mean((ph >= b["phase_lo"][:, 0, 0]) & (ph <= b["phase_hi"][:, 0, 0])))
    assert np.mean(cover_mag) >= 0.9 and np.mean(cover_ph) >= 0.9
    # the band is informative where the PRBS excites: total relative width under 20 % at 5 rad/s
    k = np.argmin(np.abs(w - 5.0))
    assert (b["mag_hi"][k, 0, 0] - b["mag_lo"][k, 0, 0]) / np.abs(G[k]) < 0.2
    # pole cloud around the true poles (continuous time, rad/s)
    pc = res.poles_continuous()
    true_pc = np.log(np.linalg.eigvals(np.asarray(TRUTH.sys.A)).astype(complex)) / DT
    assert pc.shape == (200, 2)
    upper = pc[pc.imag > 0]  # one of each complex pair
    centre = np.median(upper.real) + 1j * np.median(upper.imag)
    spread = np.sqrt(np.mean(np.abs(upper - centre) ** 2))
    assert np.abs(true_pc[true_pc.imag > 0][0] - centre) < 3 * spread


def test_results_do_not_depend_on_workers(record):
    u, y = record
    a = bootstrap(u, y, IDENT, n_boot=6, seed=3, n_jobs=1, progress=False)
    b = bootstrap(u, y, IDENT, n_boot=6, seed=3, n_jobs=2, chunk=2, progress=False)
    for ma, mb in zip(a.models, b.models, strict=True):
        np.testing.assert_array_equal(np.asarray(ma.sys.A), np.asarray(mb.sys.A))
    c = bootstrap(u, y, IDENT, n_boot=6, seed=4, progress=False)
    assert not np.array_equal(np.asarray(a.models[0].sys.A), np.asarray(c.models[0].sys.A))


def test_moesp_bootstrap_uses_its_residual_noise_model(record):
    u, y = record
    ident = functools.partial(moesp, order=2, horizon=20, delay=3, dt=DT)
    res = bootstrap(u, y, ident, n_boot=5, seed=0, progress=False)
    assert res.nominal.K is not None and res.nominal.noise_cov[0, 0] > 0
    assert len(res.zeros()) == 5


def test_bootstrap_rejects_bad_use(record):
    u, y = record
    with pytest.raises(DataError, match="IdentifiedModel"):
        bootstrap(u, y, lambda u, y: None, n_boot=2, progress=False)
    with pytest.raises(DataError, match="n_boot"):
        bootstrap(u, y, IDENT, n_boot=0, progress=False)
