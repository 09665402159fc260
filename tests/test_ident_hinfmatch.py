"""H-inf model matching: a structured model is recovered from its own black-box (ZOH, similarity-
transformed) realisation, and the published Butterworth weight is what the papers describe."""

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.ident.hinf_match import butterworth_weight, hinf_match
from rotorlab.ident.model import IdentifiedModel
from rotorlab.ident.structures import pitch_structure, rate_tf_structure, rigid_rig_structure
from rotorlab.lti import c2d_zoh, freqresp


def test_butterworth_weight_is_the_published_filter():
    W = butterworth_weight()
    assert W.nstates == 15
    g = np.abs(freqresp(W, [0.01, 7.0, 14.0])[:, 0, 0])
    assert g[0] == pytest.approx(1.0, abs=1e-9)
    assert g[1] == pytest.approx(1 / np.sqrt(2), rel=1e-9)  # -3 dB at the 7 rad/s cut-off
    assert g[2] == pytest.approx(1 / np.sqrt(1 + 2.0**30), rel=1e-6)  # |B(jw)|^2 = 1/(1 + (w/wc)^(2n))


def _black_box(structure, seed, dt=0.02):
    sysd = c2d_zoh(structure.ss(), dt)
    T = np.random.default_rng(seed).standard_normal((sysd.nstates,) * 2)
    return ct.minreal(ct.similarity_transform(sysd, T), verbose=False)  # non-physical basis, minimal


@pytest.mark.parametrize("make", [rigid_rig_structure, pitch_structure])
def test_hinf_match_recovers_structure_from_its_black_box(make):
    truth = make()
    tv = truth.values()
    bb = IdentifiedModel(sys=_black_box(truth, 1), delay=3, method="test")
    res = hinf_match(bb, truth, theta0={n: 1.3 * tv[n] for n in truth.free}, restarts=1, rng=0)
    for n in truth.free:
        assert res.params[n] == pytest.approx(tv[n], rel=0.01), n
    assert res.norm < 1e-6
    assert res.delay_s == pytest.approx(0.06)  # the black box's 3 samples at 50 Hz, reinstated
    assert res.model.delay_s() == pytest.approx(0.06)


def test_hinf_match_of_mismatched_structure_reports_the_residual_norm():
    # with the gain held 10 % off, the rate form cannot match exactly: the reported norm is the exact
    # weighted peak of the remaining error, which bounds (and is close to) its maximum on a dense grid

    truth = rigid_rig_structure()  # its defaults are the published P2-A2 test-bed model
    K_pub = published_tf("anteos-p2a2", "testbed")[0].num[0][0][0]
    wrong = rate_tf_structure(K=1.1 * K_pub, fixed=("K", "delay_s"))
    res = hinf_match(c2d_zoh(truth.ss(), 0.02), wrong, restarts=0, omega=np.logspace(-2, 2, 150))
    E = ct.series(ct.parallel(res.black_box, -res.sys), butterworth_weight())
    grid_peak = np.max(np.abs(freqresp(E, np.logspace(-2, 2, 4000))[:, 0, 0]))
    assert res.norm > 0.05
    assert res.norm >= grid_peak * (1 - 1e-6)
    assert res.norm == pytest.approx(grid_peak, rel=0.01)
