"""Batched closed-loop runs (rotorlab.sim.batch, rotorlab.sim.control.vector) against the scalar path.

Ground truth is the scalar simulator + flight software (``run_scenario``) with the same scenario, seed and gains:
the batch must reproduce it to round-off. The only non-bitwise operations are numpy's vectorised
``arcsin``/``arctan2`` in the IMU angle conversion (last-ulp differences from libm), amplified by the loop to
~1e-13 deg over a few seconds, hence the 1e-9 tolerance.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.sim import scenarios
from rotorlab.sim.batch import run_batch
from rotorlab.sim.control.flight_software import FlightSoftware
from rotorlab.sim.control.pid import DiscretePID
from rotorlab.sim.control.supervisor import Supervisor
from rotorlab.sim.control.vector import VectorPID, VectorSupervisor
from rotorlab.sim.frames import euler_deg_from_quat, euler_deg_from_quats
from rotorlab.sim.runner import make_flight_software, resolve_gains, run_scenario
from rotorlab.sim.simulator import Simulator, vehicle_mixer
from rotorlab.vehicles import load_vehicle

TOL = 1e-9
TRACES = ("theta", "q", "u_lon", "theta_true", "phi", "u_lat", "u_yaw")


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle("anteos-p2a2")


def _assert_same(batch_log: dict, scalar_log, columns=TRACES, tol=TOL):
    assert len(batch_log["t"]) == len(scalar_log["t"])
    np.testing.assert_array_equal(batch_log["t"], scalar_log["t"])
    for c in columns:
        np.testing.assert_allclose(batch_log[c], scalar_log[c], rtol=0, atol=tol, err_msg=c)


# ---------------------------------------------------------------- vectorised flight software, sample by sample
def test_vector_pid_equals_scalar_pid_per_sim_gains():
    rng = np.random.default_rng(1)
    n, dt = 6, 0.02
    gains = [LoopGains(kp=float(rng.uniform(0.1, 3)), ki=float(rng.uniform(0, 2)) * (i != 1),
                       kd=float(rng.uniform(0, 0.3)) * (i != 2), tf=float(rng.uniform(0.02, 0.1)),
                       b=float(rng.uniform(0, 1)), c=float(rng.uniform(0, 1))) for i in range(n)]
    vec = VectorPID(gains, n, dt, -5.0, 5.0)
    sca = [DiscretePID(g, dt, -5.0, 5.0, antiwindup="clamp") for g in gains]
    saturated = 0
    for _ in range(300):
        r, y = rng.normal(0, 3, n), rng.normal(0, 3, n)
        u = vec.step(r, y)
        u_ref = np.array([p.step(float(r[i]), float(y[i])) for i, p in enumerate(sca)])
        np.testing.assert_array_equal(u, u_ref)
        np.testing.assert_array_equal(vec.xi, [p.xi for p in sca])
        saturated += int(np.count_nonzero(np.abs(u) == 5.0))
    assert saturated > 50  # the anti-windup branch was exercised


def test_vector_pid_rejects_unstable_derivative_filter():
    with pytest.raises(ConfigError, match="tf"):
        VectorPID([LoopGains(kp=1.0, kd=0.1, tf=0.05), LoopGains(kp=1.0, kd=0.1, tf=0.005)], 2, 0.02)


def test_vector_supervisor_and_angles_equal_scalar():
    rng = np.random.default_rng(2)
    ang, rate = rng.uniform(-30, 30, 500), rng.normal(0, 40, 500)
    s = Supervisor()
    np.testing.assert_array_equal(VectorSupervisor().step(ang, rate), [s.step(a, r) for a, r in zip(ang, rate)])
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    np.testing.assert_allclose(euler_deg_from_quats(q), [euler_deg_from_quat(x) for x in q], rtol=0, atol=1e-12)


def test_mixer_of_many_simulations_equals_the_scalar_mixer(vehicle):
    mx = vehicle_mixer(vehicle)
    rng = np.random.default_rng(3)
    col, lat, lon, yaw = rng.uniform(-120, 120, 50), rng.normal(0, 60, 50), rng.normal(0, 60, 50), 5.0
    many = mx.mix_many(col, lat, lon, yaw)
    np.testing.assert_array_equal(many, [mx.mix(*args, yaw) for args in zip(col, lat, lon)])
    assert np.any(many == mx.out_max) and np.any(many == mx.out_min)  # the clip was exercised


def test_flight_software_of_many_simulations_names_what_it_does_not_fly(vehicle):
    gs, mx, lim = resolve_gains(vehicle, None), vehicle_mixer(vehicle), vehicle.commands
    with pytest.raises(ConfigError, match="mode 'position'"):
        FlightSoftware(gs, mx, mode="position", limits=lim, n=2)
    with pytest.raises(ConfigError, match="schedule"):
        FlightSoftware(gs, mx, limits=lim, schedule=[(1.0, gs)], n=2)
    fs = FlightSoftware(gs, mx, limits=lim, reference=lambda t: {"z_ref": -1.0}, n=2)
    meas = {c: np.zeros(2) for c in ("phi", "theta", "psi", "p", "q", "r")}
    with pytest.raises(ConfigError, match="altitude"):
        fs.step(0.0, meas)
    with pytest.raises(ConfigError, match="keeps the mode"):
        fs.set_mode("open-loop")


# ---------------------------------------------------------------- whole runs against run_scenario
def test_setpoint_with_noise_equals_scalar_runs():
    # noise on from the first tick: the per-simulation noise streams must be the scalar simulator's
    opts = {"small_step_deg": 0.0, "hold_s": 0.5}
    seeds = [0, 4, 11]
    res = run_batch("setpoint", "anteos-p2a2", 3, seeds=seeds, duration_s=2.0, options=opts, sensor_noise=True)
    for i, s in enumerate(seeds):
        rr = run_scenario("setpoint", seed=s, duration_s=2.0, options=opts, sensor_noise=True)
        _assert_same(res.log(i), rr.log, TRACES + ("theta_ref", "q_ref", "q_dot"))
        got, want = res.metrics_of(i), rr.metrics
        assert got["steps"][0]["overshoot_pct"] == pytest.approx(want["steps"][0]["overshoot_pct"], abs=1e-6)
    # noise makes the seeds differ, and the metrics table has one value per simulation
    assert np.ptp(res.traces["q"][:, 5]) > 0
    assert res.metrics["steps.0.rise_time_s"].shape == (3,)


def test_gust_with_mean_wind_equals_scalar_runs():
    # steady wind from t = 0 plus the gust: opt.wind (fuselage drag) and the rotor aero controls
    opts = {"t_start_s": 0.5, "gust_s": 1.0, "mean_wind_mps": 2.0, "from_deg": 30.0}
    res = run_batch("gust", n=2, seeds=[0, 1], duration_s=2.5, options=opts)
    rr = run_scenario("gust", seed=1, duration_s=2.5, options=opts)
    _assert_same(res.log(1), rr.log, TRACES + ("wind_u", "wind_v"))
    assert np.ptp(rr.log["theta"]) > 0.5  # the gust moved the vehicle
    assert res.metrics_of(1)["pitch"]["disturbance"] == pytest.approx(rr.metrics["pitch"]["disturbance"], abs=1e-6,
                                                                      nan_ok=True)


def test_rest_open_loop_equals_scalar_run():
    res = run_batch("rest", n=1, seeds=[3], duration_s=1.5)
    rr = run_scenario("rest", seed=3, duration_s=1.5)
    _assert_same(res.log(0), rr.log, ("theta", "q", "u_lon", "theta_true"))
    assert np.isnan(res.traces["q_ref"]).all()


def test_per_sim_gains_and_divergence_follow_the_scalar_runs(vehicle):
    std = resolve_gains(vehicle, "standard")
    p = std["pitch"]
    flipped = GainSet("flipped", {**std.axes, "pitch": AxisGains(p.outer, dataclasses.replace(p.inner, kp=-0.5))})
    sets = [std, "optimal-testbed", flipped]
    res = run_batch("setpoint", n=3, gains=sets, duration_s=3.0, sensor_noise=False)
    for i, g in enumerate(sets):
        rr = run_scenario("setpoint", gains=g, duration_s=3.0, sensor_noise=False)
        _assert_same(res.log(i), rr.log)
        assert res.stopped[i] == rr.stopped
    assert res.stopped[0] is None and "rig stop" in res.stopped[2]
    assert res.rows[2] < res.rows[0] and np.isnan(res.traces["theta"][2, -1])
    # different gains, different responses to the same step
    assert np.max(np.abs(res.traces["u_lon"][0] - res.traces["u_lon"][1])) > 1.0


def test_mass_variation_equals_a_scalar_run_on_the_edited_model(vehicle):
    res = run_batch("setpoint", n=2, seeds=[5, 6], vary={"mass": 0.2, "inertia": 0.2}, duration_s=2.5,
                    sensor_noise=False)
    mass, inertia = res.params["mass_kg"], res.params["inertia_kgm2"]
    assert abs(mass[0] - mass[1]) > 1e-3
    assert np.max(np.abs(res.traces["theta"][0] - res.traces["theta"][1])) > 1e-3
    # ground truth: the scalar simulator and flight software on a model with simulation 1's airframe
    gs = resolve_gains(vehicle, None)
    ctx = scenarios.Context(vehicle, "pitch-rig", gs, 6, 2.5, {})
    setup = scenarios.get("setpoint").setup(ctx)
    sim = Simulator("pitch-rig", vehicle, seed=6, sensor_noise=False)
    body = sim.model.body("vehicle/airframe").id
    sim.model.body_mass[body] = mass[1]
    sim.model.body_inertia[body] = inertia[1]
    mujoco.mj_setConst(sim.model, sim.data)
    sim.reset(6)
    fs = make_flight_software(vehicle, gs, setup)
    theta, u_lon = [], []
    for _ in range(res.rows[1]):
        out = fs.step(sim.time, sim.measure())
        sim.set_rotor_commands(out["rotor_pct"])
        theta.append(out["theta"])
        u_lon.append(out["u_lon"])
        sim.tick()
    np.testing.assert_allclose(res.traces["theta"][1], theta, rtol=0, atol=TOL)
    np.testing.assert_allclose(res.traces["u_lon"][1], u_lon, rtol=0, atol=TOL)


def test_seeds_reproduce_noise_and_parameters_whatever_the_batch():
    kw = dict(duration_s=1.0, options={"small_step_deg": 0.0}, sensor_noise=True, vary={"mass": 0.1, "wind": 1.0})
    a = run_batch("setpoint", n=3, seeds=[7, 8, 9], **kw)
    b = run_batch("setpoint", n=1, seeds=[8], **kw)
    np.testing.assert_array_equal(a.traces["q"][1], b.traces["q"][0])
    np.testing.assert_array_equal(a.params["mass_kg"][1], b.params["mass_kg"][0])
    np.testing.assert_array_equal(a.params["wind_ned_mps"][1], b.params["wind_ned_mps"][0])
    assert np.max(np.abs(a.traces["q"][0] - a.traces["q"][2])) > 0.01


def test_unsupported_requests_are_named():
    with pytest.raises(ConfigError, match="rope"):
        run_batch("rope-pull", n=2, duration_s=0.1)
    with pytest.raises(ConfigError, match="scene"):
        run_batch("gust", n=2, scene="free-flight", duration_s=0.1)
    with pytest.raises(ConfigError, match="own controller"):  # the vector flight software flies the cascade only
        run_batch("prbs-periodic", "tuhh-quad", n=2, duration_s=10.2)
    with pytest.raises(UnknownNameError, match="delay"):
        run_batch("setpoint", n=2, vary={"delay": 0.1}, duration_s=0.1)
    with pytest.raises(ConfigError, match="vary.delay_s"):
        run_batch("setpoint", n=2, vary={"delay_s": 0.01}, duration_s=0.1)
    with pytest.raises(ConfigError, match="seeds"):
        run_batch("setpoint", n=2, seeds=[1, 2, 3], duration_s=0.1)
