"""rotorlab.lti.d2c_zoh, the inverse of the zero-order-hold discretisation, against the exact continuous system."""

import warnings

import control as ct
import numpy as np
import pytest
import scipy.linalg as sla

from rotorlab import lti

# a rate plant with a lightly damped mount mode, a motor pole and a slow rotor-damping pole (the shape of the
# log pipeline's twin plants)
G = ct.ss(ct.tf([1.2e5], np.polymul(np.polymul([1.0, 8.4], [1.0, 0.12]), [1.0, 2 * 0.1 * 540.0, 540.0 ** 2])))


def test_d2c_zoh_inverts_c2d():
    back = lti.d2c_zoh(ct.c2d(G, 0.001, "zoh"))
    w = np.logspace(-1, 3, 30)
    assert np.allclose(lti.freqresp(back, w), lti.freqresp(G, w), rtol=1e-8)


def test_d2c_zoh_checks_the_logarithm_itself(monkeypatch):
    """scipy's own accuracy warning does not reach the user (the round trip is checked instead); a logarithm that
    does not reproduce the discrete system is refused."""
    logm = sla.logm

    def warns(M):
        warnings.warn("logm result may be inaccurate, approximate err = 2e-13", RuntimeWarning, stacklevel=2)
        return logm(M)

    monkeypatch.setattr(sla, "logm", warns)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lti.d2c_zoh(ct.c2d(G, 0.001, "zoh"))
    monkeypatch.setattr(sla, "logm", lambda M: logm(M) * (1.0 + 1e-4))
    with pytest.raises(ValueError, match="round-trip"):
        lti.d2c_zoh(ct.c2d(G, 0.001, "zoh"))
