"""Published-loop consistency: on the P2-A2 pitch-rig twin a 0.3 deg set-point step (noise off) with the published
gains has the rise time and overshoot that a discrete linear analysis of the same loop predicts.

The prediction is the twin's own linearisation (``rotorlab.sim.linearize``) resampled to the 50 Hz tick (input
held over the tick, output sampled at the tick) in closed loop with the forward-Euler 2-DoF PIDs of
``rotorlab.lti.pid2_ss``; the rise time is also checked against the published PBSID test-bed model with its
0.06 s delay (ZOH at 50 Hz). Gains are the published table (reference README), written out here on purpose.
"""

import control as ct
import numpy as np
import pytest

from rotorlab.gains import parse_gains
from rotorlab.lti import c2d_zoh_delay, pid2_ss
from rotorlab.sim.linearize import linearize
from rotorlab.sim.metrics import step_metrics
from rotorlab.sim.runner import run_scenario

DT = 0.02
STEP_DEG = 0.3
PUBLISHED = {
    "standard": {"outer": {"kp": 9.26, "kd": 1.11, "tf": 0.03},
                 "inner": {"kp": 0.257, "ki": 0.643, "kd": 0.0231, "tf": 0.0225}},
    "optimal-testbed": {"outer": {"kp": 5.4631, "kd": 0.9376, "tf": 0.0380},
                        "inner": {"kp": 0.3539, "ki": 1.8562, "kd": 0.0084, "tf": 0.0430}},
}


def _resample(sysd, n):
    """Discrete model at n times its step, input held over the n steps (exact)."""
    A, B, C, D = (np.asarray(M, float) for M in (sysd.A, sysd.B, sysd.C, sysd.D))
    nx, nu = B.shape
    M = np.zeros((nx + nu, nx + nu))
    M[:nx, :nx], M[:nx, nx:], M[nx:, nx:] = A, B, np.eye(nu)
    Mn = np.linalg.matrix_power(M, n)
    return ct.ss(Mn[:nx, :nx], Mn[:nx, nx:], C, D, sysd.dt * n)


def _closed_loop_step(plant_q_theta, gs, n=150):
    o, i = gs["pitch"].outer, gs["pitch"].inner
    Co = pid2_ss(o.kp, o.ki, o.kd, o.tf, o.b, o.c, DT)
    Co.set_inputs(["theta_ref", "theta"]), Co.set_outputs(["q_ref"])
    Ci = pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, DT)
    Ci.set_inputs(["q_ref", "q"]), Ci.set_outputs(["u"])
    P = ct.ss(plant_q_theta.A, plant_q_theta.B, plant_q_theta.C, plant_q_theta.D, DT, inputs=["u"],
              outputs=["q", "theta"])
    T = ct.interconnect([Co, Ci, P], inplist=["theta_ref"], outlist=["theta"])
    t = np.arange(n) * DT
    y = ct.forced_response(T, t, np.full(n, STEP_DEG)).outputs
    return step_metrics(t, np.ravel(y), STEP_DEG)


@pytest.fixture(scope="module")
def twin_plant():
    return _resample(linearize("pitch-rig", "anteos-p2a2", "pitch", ["gyro_pitch", "angle_pitch"]), int(round(DT / 0.001)))


@pytest.fixture(scope="module")
def published_plant():
    v = __import__("rotorlab.vehicles", fromlist=["load_vehicle"]).load_vehicle("anteos-p2a2")
    pub = v.published["testbed"]
    G = ct.tf(pub.num, pub.den)
    P = ct.ss(ct.tf([[G.num[0][0]], [np.polymul(G.num[0][0], [1.0])]], [[G.den[0][0]], [np.polymul(G.den[0][0], [1.0, 0.0])]]))
    return c2d_zoh_delay(P, DT, pub.delay_s)


@pytest.fixture(scope="module")
def twin_runs():
    out = {}
    for name, table in PUBLISHED.items():
        gs = parse_gains({"pitch": table}, name=name)
        r = run_scenario("setpoint", "anteos-p2a2", gains=gs, duration_s=3.5, sensor_noise=False,
                         options={"steps_deg": [], "small_step_deg": STEP_DEG, "hold_s": 2.5, "t0_s": 1.0})
        assert r.stopped is None
        out[name] = r.metrics["steps"][0]
    return out


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_twin_step_matches_discrete_linear_analysis(name, twin_plant, twin_runs):
    pred = _closed_loop_step(twin_plant, parse_gains({"pitch": PUBLISHED[name]}, name=name))
    got = twin_runs[name]
    assert got["rise_time_s"] == pytest.approx(pred["rise_time_s"], rel=0.10)
    assert got["overshoot_pct"] == pytest.approx(pred["overshoot_pct"], rel=0.10)
    assert got["peak_time_s"] == pytest.approx(pred["peak_time_s"], abs=DT + 1e-9)


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_twin_rise_time_matches_published_model(name, published_plant, twin_runs):
    # the twin is calibrated on this model in the 4-8 rad/s band; overshoot depends on the low-frequency
    # mismatch (the twin's rig spring), so only the rise time is held to 10 % here
    pred = _closed_loop_step(published_plant, parse_gains({"pitch": PUBLISHED[name]}, name=name))
    assert twin_runs[name]["rise_time_s"] == pytest.approx(pred["rise_time_s"], rel=0.10)
