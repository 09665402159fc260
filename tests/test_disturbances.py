"""Disturbances acting through the physics, with their logged ground truth."""

import numpy as np
import pytest
from helpers import classes_defined_in, snake_case

import rotorlab.sim.disturbances as pkg
from rotorlab.errors import ConfigError
from rotorlab.gains import parse_gains
from rotorlab.scenes import HOVER_HEIGHT_M
from rotorlab.sim.disturbances import DISTURBANCES, CosineGust, Disturbance, DrydenWind, MeanWind
from rotorlab.sim.disturbances.dryden import DrydenTurbulence
from rotorlab.sim.disturbances.dryden_wind import turbulence_axes_ned
from rotorlab.sim.disturbances.gust import one_minus_cosine
from rotorlab.sim.disturbances.input_disturbance_step import InputDisturbanceStep
from rotorlab.sim.disturbances.mean_wind import total_wind_ned
from rotorlab.sim.disturbances.recirculation_moment import RecirculationMoment
from rotorlab.sim.disturbances.rope_pull import RopePull
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator, _stable_hash
from rotorlab.vehicles import load_vehicle

STD = parse_gains({"pitch": {"outer": {"kp": 9.26, "kd": 1.11, "tf": 0.03},
                             "inner": {"kp": 0.257, "ki": 0.643, "kd": 0.0231, "tf": 0.0225}}}, name="standard")


@pytest.fixture(scope="module")
def rope_run():
    return run_scenario("rope-pull", "anteos-p2a2", gains=STD, duration_s=6.0, seed=3)


def test_rope_pulls_only_when_taut_and_releases(rope_run):
    log, n = rope_run.log, rope_run.info["notes"]
    t, T, L = log["t"], log["rope_tension"], log["rope_length"]
    assert rope_run.stopped is None
    assert np.all(T[t < n["t_pull_s"]] == 0.0)  # slack before the pull
    hold = (t > n["t_hold_s"] + 0.5) & (t < n["t_release_s"])
    assert np.all(T[hold] > 1.0)  # the controller fights the rope: it stays in tension
    assert np.all(L[T > 0] > 1.0 - 2e-3)  # tension only at the rope's length (a rope, not a spring)
    assert np.abs(log["theta"][hold].mean() - n["pull_deg"]) < 1.5  # "about 20 deg", as published
    after = t > n["t_release_s"] + 0.1
    assert np.all(T[after] == 0.0)  # released: slack again
    assert abs(log["theta"][-10:].mean()) < 1.0  # back to the null set-point


def test_rope_needs_a_rig():
    with pytest.raises(ConfigError, match="test-bed"):
        Simulator("free-flight", "anteos-p2a2", disturbances=[RopePull()])


def test_recirculation_cannot_be_hosted_in_free_flight():
    with pytest.raises(ConfigError, match="cannot be hosted by the free-flight"):
        Simulator("free-flight", "anteos-p2a2", disturbances=[RecirculationMoment(0.05, 5.0)])


def test_recirculation_moment_moves_the_open_loop_rig():
    quiet = Simulator("pitch-rig", "anteos-p2a2", sensor_noise=False)
    d = RecirculationMoment(0.2, 3.0)
    sim = Simulator("pitch-rig", "anteos-p2a2", sensor_noise=False, disturbances=[d])
    for s in (quiet, sim):
        for _ in range(100):
            s.tick()
    assert abs(quiet.true_attitude_deg()[1]) < 1e-6
    assert abs(sim.true_attitude_deg()[1]) > 0.1


def test_logged_dryden_wind_is_the_generator_output_for_the_seed():
    seed, dur = 11, 2.0
    r = run_scenario("hover", "anteos-p2a2", gains=STD, seed=seed, duration_s=dur, options={"switch_s": None})
    rng = np.random.default_rng([seed, _stable_hash("dryden")])
    n = r.log.n
    v = load_vehicle("anteos-p2a2")
    span_m = 2.0 * (v.arm_m + v.rotor.radius_m)  # tip to tip: the span the air's rotation is felt over
    gen, rot = DrydenTurbulence(2.5, HOVER_HEIGHT_M, rng=rng).generate_with_rates(int(np.ceil(dur / 0.02)) + 1, 0.02,
                                                                                  span_m)
    axes = turbulence_axes_ned(0.0)
    expected = gen[:n] @ axes.T + np.array([-2.5, 0.0, 0.0])  # plus the mean headwind (NED)
    logged = np.column_stack([r.log["wind_u"], r.log["wind_v"], r.log["wind_w"]])
    np.testing.assert_allclose(logged, expected, rtol=0, atol=1e-12)
    # the air's rotation, in deg/s about north, east, down
    logged = np.column_stack([r.log["air_rate_n"], r.log["air_rate_e"], r.log["air_rate_d"]])
    np.testing.assert_allclose(logged, np.degrees(rot[:n] @ axes.T), rtol=0, atol=1e-12)
    assert r.log.units["air_rate_e"] == "deg/s"


def test_logged_wind_is_total_wind_ned_bit_for_bit():
    """The logged wind (summed in floats every tick) is total_wind_ned's numpy sum of the wind disturbances,
    the batched runner's, bit for bit, signed zeros included (a mean wind without vertical component)."""
    winds = [MeanWind(2.5, 30.0), DrydenWind(2.5, 5.0, 3.0, 40.0), CosineGust(0.5, 1.0, 3.0, 90.0)]
    sim = Simulator("free-flight", "anteos-p2a2", sensor_noise=False, disturbances=winds)
    for _ in range(100):
        logged = np.array([winds[0].values(sim)[k] for k in ("wind_u", "wind_v", "wind_w")])
        total = total_wind_ned(winds, sim.time)
        assert np.array_equal(logged, total) and np.array_equal(np.signbit(logged), np.signbit(total))
        # the others log their own ground truth only: the Dryden record's air rotation
        assert set(winds[1].values(sim)) == {"air_rate_n", "air_rate_e", "air_rate_d"} and winds[2].values(sim) == {}
        sim.tick()


def test_one_minus_cosine_gust_shape_in_the_log():
    r = run_scenario("gust", "anteos-p2a2", gains=STD, duration_s=4.0,
                     options={"amplitude_mps": 4.0, "t_start_s": 1.0, "gust_s": 1.0})
    t, u = r.log["t"], r.log["wind_u"]
    np.testing.assert_allclose(u, -one_minus_cosine(t, 1.0, 1.0, 4.0), atol=1e-12)  # headwind: -north
    assert np.all(u[(t < 1.0) | (t > 2.0)] == 0.0)
    assert u.min() == pytest.approx(-4.0) and t[np.argmin(u)] == pytest.approx(1.5)
    assert np.all(r.log["wind_v"] == 0.0) and np.all(r.log["wind_w"] == 0.0)
    # the gust acts physically: a headwind pitches the rig nose up before the loop recovers
    assert r.metrics["pitch"]["disturbance"]["peak_deviation"] > 0.5


def test_same_seed_gives_bit_identical_logs():
    kw = dict(gains=STD, duration_s=1.5, options={"switch_s": None})
    a, b = (run_scenario("hover", "anteos-p2a2", seed=5, **kw) for _ in range(2))
    c = run_scenario("hover", "anteos-p2a2", seed=6, **kw)
    for col in ("theta", "q", "u_lon", "x", "wind_u", "wind_w"):
        assert np.array_equal(a.log[col], b.log[col], equal_nan=True), col
    assert not np.array_equal(a.log["wind_u"], c.log["wind_u"])


# one example per registered disturbance and a scene that hosts it: a new entry in DISTURBANCES needs one here
_EXAMPLES = {
    "mean-wind": (lambda: MeanWind(3.0, 0.0), "pitch-rig"),
    "dryden": (lambda: DrydenWind(3.0, HOVER_HEIGHT_M, 1.0), "free-flight"),
    "cosine-gust": (lambda: CosineGust(0.0, 0.5, 4.0), "pitch-rig"),
    "recirculation": (lambda: RecirculationMoment(0.3, 1.0), "pitch-rig"),
    "input-step": (lambda: InputDisturbanceStep(0.1, t_s=0.0), "pitch-rig"),
    "rope": (lambda: RopePull(pull_deg=-20.0, t_pull_s=0.0, ramp_s=0.2, length_m=1.0, slack_m=0.05), "pitch-rig"),
}


def test_registry_holds_every_disturbance_in_a_file_named_after_it():
    defined = set()
    for module, obj in classes_defined_in(pkg, Disturbance):
        # concrete disturbances: the ones with a name of their own (the base classes keep the default one)
        if "name" in vars(obj):
            defined.add(obj)
            assert module == snake_case(obj.__name__), (module, obj.__name__)
    assert defined == set(DISTURBANCES.values())
    assert all(cls.name == name for name, cls in DISTURBANCES.items())
    assert set(pkg.__all__) >= {cls.__name__ for cls in defined}
    assert set(_EXAMPLES) == set(DISTURBANCES)


def test_input_disturbance_is_a_command_at_the_plant_input():
    # ref. 002 fig. 4a adds d to the controller output before the plant: 10 % of full command reaches the
    # airframe through the rotors' delay and lag exactly as a 10 % pitch command does, and not before the delay
    v = load_vehicle("tuhh-quad")
    dist = Simulator("pitch-rig", v, sensor_noise=False, disturbances=[InputDisturbanceStep(0.1, t_s=0.0)])
    cmd = Simulator("pitch-rig", v, sensor_noise=False)
    quiet = Simulator("pitch-rig", v, sensor_noise=False)
    hover = [v.hover_collective_pct, 0.0, 0.0, 0.0]
    before = int(v.rotor.delay_s[0] / v.control_dt_s)  # ticks within the pitch rotors' transport delay
    for k in range(40):
        dist.set_commands(hover)
        cmd.set_commands([v.hover_collective_pct, 0.0, 10.0, 0.0])
        quiet.set_commands(hover)
        for s in (dist, cmd, quiet):
            s.tick()
        np.testing.assert_allclose(dist.data.qvel, cmd.data.qvel, rtol=1e-12, atol=1e-12)
        if k < before:
            np.testing.assert_array_equal(dist.data.qvel, quiet.data.qvel)
    assert abs(dist.data.qvel).max() > 0.1


@pytest.mark.parametrize("name", sorted(DISTURBANCES))
def test_every_registered_disturbance_acts_on_the_physics_and_logs_its_columns(name):
    make, scene = _EXAMPLES[name]
    quiet = Simulator(scene, "anteos-p2a2", sensor_noise=False)
    dist = make()
    assert isinstance(dist, DISTURBANCES[name])
    sim = Simulator(scene, "anteos-p2a2", sensor_noise=False, disturbances=[dist])
    for s in (quiet, sim):
        for _ in range(25):
            s.tick()
    assert set(dist.values(sim)) == set(dist.columns)
    # the state left the undisturbed trajectory: the disturbance reached the physics
    assert np.max(np.abs(sim.data.qvel - quiet.data.qvel)) > 1e-4
