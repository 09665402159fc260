"""Supervisor: keeps the P2-A2 test-bed model within +-20 deg under the published PRBS campaigns, silent
while the attitude is small."""

import numpy as np
import pytest
from helpers import p2a2_testbed_angle_rate

from rotorlab.errors import ConfigError
from rotorlab.excitation import prbs
from rotorlab.sim.control.supervisor import Supervisor

DT = 0.02


def _simulate(u_exc, supervisor):
    # the test-bed model with its 3-sample delay applied below
    P = p2a2_testbed_angle_rate(DT)
    A, B, C = (np.asarray(M).tolist() for M in (P.A, P.B[:, 0], P.C))
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = A
    b0, b1, b2 = B
    (c00, c01, c02), (c10, c11, c12) = C
    x0 = x1 = x2 = 0.0
    delay = [0.0, 0.0, 0.0]
    theta = np.empty(u_exc.size)
    u_sup = np.zeros(u_exc.size)
    # scalar loop: the supervisor is a per-sample nonlinearity, and 3x3 numpy products per sample are slower
    for k, u in enumerate(u_exc.tolist()):
        th = c00 * x0 + c01 * x1 + c02 * x2
        q = c10 * x0 + c11 * x1 + c12 * x2
        theta[k] = th
        if supervisor is not None:
            u_sup[k] = supervisor.step(th, q)
        delay.append(u + u_sup[k])
        ud = delay.pop(0)
        x0, x1, x2 = (a00 * x0 + a01 * x1 + a02 * x2 + b0 * ud, a10 * x0 + a11 * x1 + a12 * x2 + b1 * ud,
                      a20 * x0 + a21 * x1 + a22 * x2 + b2 * ud)
    return theta, u_sup


# published campaigns (switching-time range s, amplitude %), with and without a 1.5 % trim error: a constant
# bias integrates into a steady drift, so every campaign then needs the supervisor; without bias only the slow
# campaign drifts past the limit
@pytest.mark.parametrize("hold_range_s,amp,bias", [((0.4, 0.8), 11.0, 0.0), ((0.4, 0.8), 7.0, 0.0),
                                                   ((0.4, 0.8), 11.0, 1.5), ((0.2, 0.4), 9.0, 1.5),
                                                   ((0.1, 0.2), 7.0, 1.5)])
@pytest.mark.parametrize("seed", [0, 1])
def test_supervisor_keeps_limit_and_is_silent_when_small(hold_range_s, amp, bias, seed):
    u = prbs(duration_s=90.0, dt=DT, hold_range_s=hold_range_s, amplitude=amp, seed=seed) + bias
    theta_free, _ = _simulate(u, None)
    assert np.max(np.abs(theta_free)) > 20.0  # the experiment needs supervision at all
    theta, u_sup = _simulate(u, Supervisor(limit_deg=20.0))
    assert np.max(np.abs(theta)) <= 20.0
    # silent inside the band (|theta| <= 0.75 * 20 deg): the data there are genuinely open loop
    assert np.all(u_sup[np.abs(theta) <= 15.0] == 0.0)
    # and it only ever pushes back towards zero
    assert np.all(u_sup * np.sign(theta) <= 0.0)


def test_supervisor_law_and_arguments():
    s = Supervisor(limit_deg=20.0, engage_frac=0.75, kp=4.0, kd=0.5, u_limit_pct=30.0)
    assert s.step(14.9, 100.0) == 0.0 and not s.active
    assert s.step(17.0, 2.0) == pytest.approx(-(4.0 * 2.0 + 0.5 * 2.0)) and s.active
    assert s.step(-17.0, -2.0) == pytest.approx(4.0 * 2.0 + 0.5 * 2.0)
    assert s.step(19.0, -100.0) == 0.0  # already moving back fast: never pushes towards the limit
    assert s.step(40.0, 50.0) == -30.0  # saturated
    with pytest.raises(ConfigError, match="engage_frac"):
        Supervisor(engage_frac=1.5)
