"""VAF, simulation with estimated initial state, order selection, non-parametric FRFs and the nu-gap."""

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.errors import DataError
from rotorlab.excitation import prbs
from rotorlab.ident import (
    IdentifiedModel,
    chordal_distance,
    etfe,
    model_frf,
    nugap,
    select_order,
    simulate,
    stability_margin_bpc,
    vaf,
    welch_frf,
)
from rotorlab.lti import c2d_zoh

DT = 0.02
TESTBED = published_tf("anteos-p2a2", "testbed")[0]  # P2-A2 PBSID test-bed model
FLIGHT = published_tf("anteos-p2a2", "flight")[0]  # P2-A2 PBSID in-flight model


def test_vaf_definition():
    rng = np.random.default_rng(0)
    y = rng.standard_normal((1000, 2))
    e = 0.1 * rng.standard_normal((1000, 2))
    expected = (1 - e.var(axis=0) / y.var(axis=0)) * 100
    np.testing.assert_allclose(vaf(y, y + e), expected)
    assert vaf(y[:, 0], -y[:, 0])[0] == 0.0  # clipped at zero
    with pytest.raises(DataError, match="shape"):
        vaf(y, y[:, :1])


def test_simulate_estimates_the_initial_state_including_the_delay_line():
    m = IdentifiedModel(c2d_zoh(TESTBED, DT), delay=3)
    u = prbs(1500, DT, hold_range_s=(0.05, 0.4), amplitude=7.0, seed=1)
    y = m.simulate(u)[:, 0]
    # a window that starts mid-record: plant state and the three inputs in the delay line are unknown
    uw, yw = u[500:], y[500:]
    assert np.max(np.abs(simulate(m, uw)[:, 0] - yw)) > 1e-2 * np.abs(yw).max()  # zero state: transient error
    np.testing.assert_allclose(simulate(m, uw, x0="estimate", y=yw)[:, 0], yw, atol=1e-8 * np.abs(yw).max())
    with pytest.raises(DataError, match="needs the measured output"):
        simulate(m, uw, x0="estimate")


def test_select_order_finds_true_order():
    G = c2d_zoh(TESTBED, DT)
    u = prbs(4000, DT, hold_range_s=(0.05, 0.8), amplitude=7.0, seed=2)
    y0 = IdentifiedModel(G, delay=3).simulate(u)[:, 0]
    y = y0 + 0.05 * y0.std() * np.random.default_rng(3).standard_normal(len(y0))
    best, table = select_order(u[:3000], y[:3000], u[3000:], y[3000:], method="pbsid", orders=[1, 2, 3],
                               horizons=[(20, 10)], delay=3, dt=DT)
    vafs = {row["settings"]["order"]: row["vaf_cv_mean"] for row in table}
    assert vafs[1] < vafs[2] - 1.0  # first order underfits clearly
    assert best.settings["order"] in (2, 3) and max(vafs.values()) > 99.0
    assert abs(vafs[3] - vafs[2]) < 0.5  # more states add nothing


def test_select_order_refusing_every_candidate_names_the_grid_and_why():
    """Every candidate refused (here: none with a ZOH continuous equivalent is wanted, so all are refused): the
    error names the method, the grid and each candidate's fate, not only that nothing was found."""
    G = c2d_zoh(TESTBED, DT)
    u = prbs(1000, DT, hold_range_s=(0.05, 0.8), amplitude=7.0, seed=2)
    y = IdentifiedModel(G, delay=3).simulate(u)[:, 0]

    def never(m):
        return False

    with pytest.raises(DataError, match=r"no pbsid model of the grid \(orders \[1, 2\], horizons \[\(20, 10\)\]\)"
                                        r".*accepted by never: order 1 \(refused by accept\), order 2 \(refused"):
        select_order(u[:700], y[:700], u[700:], y[700:], method="pbsid", orders=iter([1, 2]), horizons=[(20, 10)],
                     delay=3, dt=DT, accept=never)


def test_nugap_published_p2a2_models():
    # paper: 0.0741 from the unrounded models; the rounded published coefficients give 0.0735
    assert nugap(TESTBED, FLIGHT) == pytest.approx(0.0735, abs=5e-4)
    # the sup is accurate: a dense grid never exceeds it
    w = np.logspace(-2, 3, 20000)
    k = chordal_distance(TESTBED, FLIGHT, w)
    assert nugap(TESTBED, FLIGHT) >= k.max() - 1e-9
    assert nugap(TESTBED, FLIGHT) - k.max() < 1e-6


def test_nugap_properties_and_winding_condition():
    G = ct.tf([1.0], [1.0, 1.0])
    assert nugap(G, G) == pytest.approx(0.0, abs=1e-12)
    assert nugap(TESTBED, FLIGHT) == pytest.approx(nugap(FLIGHT, TESTBED), abs=1e-9)
    # analytic: k/(s+1) vs 1/(s+1) peaks at w = sqrt(k - 1) with kappa = (k - 1)/(k + 1)
    k = 2.0
    assert nugap(ct.tf([k], [1, 1]), G) == pytest.approx((k - 1) / (k + 1), rel=1e-9)
    # stable vs unstable with the same |G(jw)|: the winding condition fails
    assert nugap(ct.tf([1.0], [1.0, -1.0]), G) == 1.0
    # sign flip: det(1 + G2* G1) = 1 - |G|^2 vanishes where |G| = 1
    assert nugap(G, -G * 2) == 1.0
    # integrators on the imaginary axis are allowed: 1/s vs 1/(s + 0.1) -> 0.1 / sqrt(1 + 0.01)
    assert nugap(ct.tf([1.0], [1.0, 0.0]), ct.tf([1.0], [1.0, 0.1])) == pytest.approx(0.1 / np.sqrt(1.01), rel=1e-6)
    # same unstable plant, slightly different gain: small gap
    assert nugap(ct.tf([1.0], [1.0, -1.0]), ct.tf([1.1], [1.0, -1.0])) < 0.1


def test_nugap_discrete_matches_continuous_at_fast_sampling():
    d = nugap(c2d_zoh(TESTBED, 0.001), c2d_zoh(FLIGHT, 0.001))
    assert d == pytest.approx(nugap(TESTBED, FLIGHT), abs=2e-4)


def test_nugap_mimo_reduces_to_siso_for_diagonal_systems():
    G1 = ct.append(ct.ss(TESTBED), ct.ss(ct.tf([1.0], [1.0, 1.0])))
    G2 = ct.append(ct.ss(FLIGHT), ct.ss(ct.tf([1.0], [1.0, 1.0])))
    assert nugap(G1, G2) == pytest.approx(nugap(TESTBED, FLIGHT), abs=1e-6)


def test_stability_margin_bpc_analytic():
    # P = 1/(s+1), C = 1: b = inf_w 1/sigma_max([P;1](1+P)^-1[1 1]) = min_w |1+P| / sqrt(2 (1+|P|^2))
    w = np.logspace(-3, 3, 20001)
    P = 1 / (1j * w + 1)
    expected = np.min(np.abs(1 + P) / np.sqrt(2 * (1 + np.abs(P) ** 2)))
    assert stability_margin_bpc(ct.tf([1.0], [1.0, 1.0]), ct.tf([1.0], [1.0])) == pytest.approx(expected, rel=1e-4)
    assert stability_margin_bpc(ct.tf([1.0], [1.0, -1.0]), ct.tf([0.5], [1.0])) == 0.0  # loop unstable


def test_welch_frf_matches_the_plant_where_coherent():
    G = c2d_zoh(TESTBED, DT)
    u = prbs(10000, DT, hold_range_s=(0.05, 0.4), amplitude=7.0, seed=4)
    y0 = IdentifiedModel(G).simulate(u)[:, 0]
    y = y0 + 0.05 * y0.std() * np.random.default_rng(5).standard_normal(len(y0))
    est = welch_frf(u, y, DT, nperseg=512)
    H = model_frf(G, est.w_rad_s)[:, 0, 0]
    band = est.reliable & (est.w_rad_s > 1.0) & (est.w_rad_s < 30.0)
    assert band.sum() > 20
    assert np.max(np.abs(est.H[band] / H[band] - 1)) < 0.1
    e = etfe(u, y, DT, smooth_bins=31)
    He = model_frf(G, e.w_rad_s)[:, 0, 0]
    sel = e.reliable & (e.w_rad_s > 1.0) & (e.w_rad_s < 30.0)
    assert np.median(np.abs(e.H[sel] / He[sel] - 1)) < 0.05
    # where the input carries no power the estimate is flagged
    slow = np.sin(0.5 * np.arange(10000) * DT)
    est2 = welch_frf(slow, IdentifiedModel(G).simulate(slow)[:, 0] + 0.01 * np.random.default_rng(6).standard_normal(10000), DT)
    assert not est2.reliable[est2.w_rad_s > 20].any()
