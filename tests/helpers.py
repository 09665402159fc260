"""Plain helpers shared by test modules (fixtures live in conftest.py): a ground-truth plant written out
independently of the library, and a reader of a pipeline summary's claim metrics."""

import control as ct
import numpy as np

from rotorlab.lti import c2d_zoh


def p2a2_testbed_angle_rate(dt: float) -> ct.StateSpace:
    """The P2-A2 test-bed pitch model (reference 000, PBSID) ``q/u = 12.517 (s + 2.906) / (s^2 + 5.583 s +
    21.3)``, integrated to the angle in continuous time: ``u`` (%) -> ``[theta (deg), q (deg/s)]``, ZOH at ``dt``
    (s). The 3-sample input delay is the caller's."""
    G = ct.tf2ss(ct.tf([12.517, 12.517 * 2.906], [1, 5.583, 21.3]))
    A = np.block([[G.A, np.zeros((2, 1))], [G.C, np.zeros((1, 1))]])
    B = np.vstack([G.B, G.D])
    C = np.vstack([np.hstack([np.zeros((1, 2)), np.ones((1, 1))]), np.hstack([G.C, np.zeros((1, 1))])])
    return c2d_zoh(ct.ss(A, B, C, np.zeros((2, 1))), dt)


def claim_metrics(summary: dict):
    """``m(scenario, metric, set)``: the metric's magnitude in a pipeline summary, infinite where the set has
    none (never settled, never recovered: the summary leaves it out or stores None). A metric that no gain set
    of the scenario has is a KeyError, so a misspelt key cannot pass as infinity against infinity."""
    v = summary["validation"]

    def m(sc, key, name):
        if not any(key in r for r in v[sc].values()):
            raise KeyError(f"no gain set of {sc!r} has the metric {key!r}")
        x = v[sc][name].get(key)
        return np.inf if x is None else abs(x)

    return m
