"""Domain randomisation: one draw function (rotorlab.sim.randomize) with the documented distributions, used by
the gym envs, ``rotorlab montecarlo`` and the batched runner."""

import numpy as np
import pytest
from scipy import stats

from rotorlab.commands import montecarlo
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.scenes import PHYSICS_DT_S
from rotorlab.sim import env_base, randomize
from rotorlab.sim.batch import run_batch
from rotorlab.vehicles import load_vehicle

N = 3000


@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle("anteos-p2a2")


@pytest.fixture(scope="module")
def draws(vehicle):
    rng = np.random.default_rng(1)
    spreads = {"mass": 0.2, "inertia": 0.3, "motor_lag": 0.1, "delay_s": (0.04, 0.08), "imu_mount": 0.25, "wind": 4.0}
    return [randomize.draw(vehicle, spreads, rng, PHYSICS_DT_S) for _ in range(N)]


def _uniform(x, lo, hi):
    x = np.asarray(x)
    assert lo <= x.min() and x.max() <= hi
    assert stats.kstest(x, stats.uniform(lo, hi - lo).cdf).pvalue > 1e-3


def test_factors_are_uniform_on_the_documented_intervals(draws):
    _uniform([d.mass_factor for d in draws], 0.8, 1.2)
    _uniform([d.lag_factor for d in draws], 0.9, 1.1)
    _uniform([d.imu_mount_factor for d in draws], 0.75, 1.25)
    _uniform([d.wind_speed_mps for d in draws], 0.0, 4.0)
    _uniform([d.wind_from_deg for d in draws], 0.0, 360.0)


def test_inertia_factors_are_independent_per_axis_and_physical(draws, vehicle):
    f = np.array([d.inertia_factors for d in draws])
    for k in range(3):
        assert 0.7 <= f[:, k].min() and f[:, k].max() <= 1.3
    assert abs(np.corrcoef(f[:, 0], f[:, 1])[0, 1]) < 0.1  # one factor each, not one for all
    J = np.sort(f * np.asarray(vehicle.inertia_kgm2), axis=1)
    assert np.all(J[:, 0] + J[:, 1] >= J[:, 2])  # the triangle inequality of a rigid body


def test_delay_is_a_whole_number_of_physics_steps_uniform_over_the_range(draws):
    steps = np.array([d.delay_s for d in draws]) / PHYSICS_DT_S
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    counts = np.bincount(np.round(steps).astype(int) - 40)
    assert len(counts) == 41 and counts.min() > 0  # 40 ... 80 ms, every step reachable
    assert stats.chisquare(counts).pvalue > 1e-3


def test_apply_puts_the_draw_into_the_vehicle(vehicle):
    d = randomize.Draw(1.1, (0.9, 1.0, 1.2), 1.05, 0.07, 0.8)
    v = randomize.apply(vehicle, d)
    assert v.mass_kg == pytest.approx(1.1 * vehicle.mass_kg)
    np.testing.assert_allclose(v.inertia_kgm2, np.multiply(vehicle.inertia_kgm2, (0.9, 1.0, 1.2)))
    np.testing.assert_allclose(v.rotor.lag_s, np.multiply(vehicle.rotor.lag_s, 1.05))
    assert v.rotor.delay_s == (0.07,) * 4
    assert v.imu.mount_frequency_hz == pytest.approx(0.8 * vehicle.imu.mount_frequency_hz)


def test_bad_spreads_are_named():
    with pytest.raises(UnknownNameError, match="weight"):
        randomize.check_spreads({"weight": 0.1})
    with pytest.raises(ConfigError, match=r"randomize.mass"):
        randomize.check_spreads({"mass": 1.5})
    with pytest.raises(ConfigError, match=r"randomize.delay_s"):
        randomize.check_spreads({"delay_s": (0.08, 0.04)})


def test_envs_montecarlo_and_batch_all_draw_through_the_one_function(vehicle, monkeypatch):
    calls = []
    real = randomize.draw

    def spy(*args, **kwargs):
        d = real(*args, **kwargs)
        calls.append(d)
        return d

    monkeypatch.setattr(randomize, "draw", spy)
    # gym envs
    v, _ = env_base.randomized_vehicle(vehicle, {"mass": 0.1}, np.random.default_rng(0), PHYSICS_DT_S)
    assert v.mass_kg == pytest.approx(vehicle.mass_kg * calls[-1].mass_factor)
    # rotorlab montecarlo
    spec, params = montecarlo.draw(vehicle, {"mass": 0.1, "delay": 0.02}, np.random.SeedSequence(3))
    assert spec.mass_kg == pytest.approx(vehicle.mass_kg * calls[-1].mass_factor) == \
        pytest.approx(vehicle.mass_kg * params["mass_factor"])
    assert spec.rotor.delay_s[0] == params["delay_s"] and 0.06 <= params["delay_s"] <= 0.08
    # batched runner: one draw per simulation, seeded by the simulation's seed
    n0 = len(calls)
    res = run_batch("setpoint", vehicle, 2, seeds=[4, 5], vary={"mass": 0.1, "wind": 2.0}, duration_s=0.1,
                    sensor_noise=False)
    assert len(calls) - n0 == 2
    d5 = real(vehicle, {"mass": 0.1, "wind": 2.0}, np.random.default_rng([5, 0x76617279]), PHYSICS_DT_S)
    assert res.params["mass_kg"][1] / res.params["mass_kg"][0] == pytest.approx(
        d5.mass_factor / calls[n0].mass_factor)
    assert np.hypot(*res.params["wind_ned_mps"][1, :2]) == pytest.approx(d5.wind_speed_mps)
