"""The flight-log rate plant structures (ident/flightlogs/plant_structures.py): every registered axis against its
formula written out by hand, the autopilot's gyro low-pass as the exact discrete filter after the ZOH plant, and
the motors' parameters shared into yaw."""

import control as ct
import numpy as np
import pytest

from rotorlab.autopilots.filters import butter2_ss
from rotorlab.ident.flightlogs.plant_structures import (
    MOTOR_PARAMS,
    STRUCTURES,
    fitted_plant,
    plant_structure,
    rate_angle_plant_structure,
)
from rotorlab.ident.greybox import oe_fit, simulate_greybox
from rotorlab.lti import c2d_zoh_delay

DT = 0.004
# per structure: parameters away from the defaults and the continuous response written by hand, delay apart
FORMULAS = {
    "rate-plant": ({"K": 107.0, "tau_s": 0.037},
                   lambda s, p: p["K"] / (s * (p["tau_s"] * s + 1))),
    # the yaw derivation of the module docstring: drag-torque gain, spin-up zero, in-plane drag pole, motor lag
    "yaw-rate-plant": ({"K": 7.5, "z_rad_s": 2.434, "a_rad_s": 0.41, "tau_s": 0.037},
                       lambda s, p: p["K"] * (1 + s / p["z_rad_s"]) / ((p["tau_s"] * s + 1) * (s + p["a_rad_s"]))),
}


@pytest.mark.parametrize("axis", sorted(STRUCTURES))
def test_every_axis_structure_is_its_formula(axis):
    m = plant_structure(axis)
    assert m.name in FORMULAS, f"structure {m.name} of {axis} has no hand-written formula in this test"
    theta, formula = FORMULAS[m.name]
    sys = m.ss(theta)
    for w in (0.3, 2.0, 27.0, 300.0):
        assert complex(ct.evalfr(sys, 1j * w)) == pytest.approx(formula(1j * w, theta), rel=1e-9)
    assert set(MOTOR_PARAMS) <= set(m.names)


def test_yaw_is_not_the_roll_shape():
    assert plant_structure("yaw").name == "yaw-rate-plant"
    assert plant_structure("roll").name == plant_structure("pitch").name == "rate-plant"
    with pytest.raises(KeyError, match="no rate plant structure"):
        plant_structure("collective")


def test_gyro_filter_follows_the_zoh_plant_and_stays_in_the_fit():
    F = lambda dt: butter2_ss(1.0 / dt, 40.0)  # noqa: E731 - PX4's IMU_GYRO_CUTOFF default
    m = plant_structure("yaw", F)
    theta = {**FORMULAS["yaw-rate-plant"][0], "delay_s": 0.026}
    want = ct.series(c2d_zoh_delay(plant_structure("yaw").ss(theta), DT, 0.026), butter2_ss(1 / DT, 40.0))
    for w in (1.0, 100.0, 350.0):
        zw = np.exp(1j * w * DT)
        assert complex(ct.evalfr(m.discretize(DT, theta), zw)) == pytest.approx(complex(ct.evalfr(want, zw)),
                                                                                rel=1e-9)
    # noise-free data through the filtered structure: the fit returns the parameters and its discrete model
    # keeps the filter
    u = np.random.default_rng(0).standard_normal(3000)
    y = simulate_greybox(m, u, DT, theta)
    res = oe_fit(m, u, y, DT, {"K": 6.0, "z_rad_s": 2.0, "a_rad_s": 0.3, "tau_s": 0.03, "delay_s": 0.02})
    for k, v in theta.items():
        assert res.params[k] == pytest.approx(v, rel=1e-4)
    got = res.discrete().with_delay()
    for w in (1.0, 100.0, 350.0):
        zw = np.exp(1j * w * DT)
        assert complex(ct.evalfr(got, zw)) == pytest.approx(complex(ct.evalfr(want, zw)), rel=1e-4)


def test_the_angle_loop_structure_filters_the_rate_and_not_the_attitude():
    """Through the angle loop the fit sees two outputs: the rate through the autopilot's gyro low-pass (as the rate
    controller and the log see it) and the attitude, which the estimator integrates from the unfiltered gyro. By
    hand: ``[F G; G / s]`` with ``G = K e^(-s d) / (s (tau s + 1))`` discretised exactly."""
    F = lambda dt: butter2_ss(1.0 / dt, 20.0)  # noqa: E731 - ArduCopter's INS_GYRO_FILTER default
    theta = {"K": 198.0, "tau_s": 0.015, "delay_s": 0.0061}
    G = ct.ss(ct.tf([theta["K"]], [theta["tau_s"], 1.0, 0.0]))
    rate = ct.series(c2d_zoh_delay(G, DT, theta["delay_s"]), butter2_ss(1 / DT, 20.0))
    att = c2d_zoh_delay(ct.ss(ct.series(G, ct.tf([1.0], [1.0, 0.0]))), DT, theta["delay_s"])
    got = rate_angle_plant_structure(gyro_filter=F).discretize(DT, theta)
    bare = rate_angle_plant_structure().discretize(DT, theta)
    for w in (0.5, 20.0, 125.0, 500.0):
        zw = np.exp(1j * w * DT)
        g = ct.evalfr(got, zw)
        assert complex(g[0, 0]) == pytest.approx(complex(ct.evalfr(rate, zw)), rel=1e-8)
        assert complex(g[1, 0]) == pytest.approx(complex(ct.evalfr(att, zw)), rel=1e-8)
        assert complex(ct.evalfr(bare, zw)[1, 0]) == pytest.approx(complex(g[1, 0]), rel=1e-12)
    # the filter's phase at 20 Hz is the lag the structure without it would fit into the motors: 90 deg
    z20 = np.exp(2j * np.pi * 20.0 * DT)
    lag_deg = np.degrees(np.angle(ct.evalfr(bare, z20)[0, 0] / ct.evalfr(got, z20)[0, 0]))
    assert lag_deg == pytest.approx(90.0, abs=1.0)


def test_motors_given_are_fixed():
    m = plant_structure("yaw", motors={"tau_s": 0.0368, "delay_s": 0.0266})
    assert m.free == ["K", "z_rad_s", "a_rad_s"]
    assert m.values()["tau_s"] == 0.0368 and m.values()["delay_s"] == 0.0266


def test_yaw_motor_paths_are_the_mean_of_the_rotor_groups_each_with_its_delay():
    """Two motor paths (a plus frame's roll pair and pitch pair): the discrete model is the mean of two
    single-path structures, each discretised exactly with its own delay, and the paths' parameters are fixed."""
    paths = [{"tau_s": 0.0369, "delay_s": 0.024}, {"tau_s": 0.0371, "delay_s": 0.0285}]
    m = plant_structure("yaw", motors=paths)
    assert m.free == ["K", "z_rad_s", "a_rad_s"] and m.delay_s() == 0.024
    theta = {"K": 7.5, "z_rad_s": 2.434, "a_rad_s": 0.41}
    got = m.discretize(DT, theta)
    one = [plant_structure("yaw", motors=p).discretize(DT, theta) for p in paths]
    for w in (0.5, 30.0, 300.0, 700.0):
        zw = np.exp(1j * w * DT)
        want = 0.5 * sum(complex(ct.evalfr(g, zw)) for g in one)
        assert complex(ct.evalfr(got, zw)) == pytest.approx(want, rel=1e-9)
    # the delay-free sum is the formula with the paths' mean lag
    formula = lambda s: theta["K"] * (1 + s / theta["z_rad_s"]) / (s + theta["a_rad_s"]) * np.mean(  # noqa: E731
        [1 / (p["tau_s"] * s + 1) for p in paths])
    assert complex(ct.evalfr(m.ss(theta), 300j)) == pytest.approx(formula(300j), rel=1e-9)


def test_imu_mount_is_the_base_excited_spring_damper_at_the_output():
    m = plant_structure("roll", imu_mount=(60.0, 0.15))
    assert m.free == ["K", "tau_s", "delay_s"]
    theta = FORMULAS["rate-plant"][0]
    w_m = 2 * np.pi * 60.0
    for w in (3.0, 100.0, w_m, 1000.0):
        s = 1j * w
        mount = (2 * 0.15 * w_m * s + w_m**2) / (s**2 + 2 * 0.15 * w_m * s + w_m**2)
        assert complex(ct.evalfr(m.ss(theta), s)) == pytest.approx(FORMULAS["rate-plant"][1](s, theta) * mount,
                                                                   rel=1e-9)


def test_fitted_plant_merges_the_motor_paths_at_their_mean_delay():
    """A two-path yaw fit read back as one input: with equal paths it is the one-path structure exactly; with
    delays 24 and 28 ms it is that plant at 26 ms within cos(w * 2 ms) in gain over 1-30 rad/s; a name no
    structure has, or missing parameters, give None."""
    one = {"K": 7.5, "z_rad_s": 2.4, "a_rad_s": 0.41, "tau_s": 0.037, "delay_s": 0.026}
    w = np.logspace(0.0, np.log10(30.0), 9)
    G1, d1 = fitted_plant("yaw-rate-plant", one)
    G2, d2 = fitted_plant("yaw-rate-plant", {**one, "tau2_s": 0.037, "delay2_s": 0.026})
    assert d1 == d2 == 0.026 and G2.ninputs == 1
    assert np.allclose(G1(1j * w), G2(1j * w), rtol=1e-12)
    s = 1j * w
    paths = {**one, "delay_s": 0.024, "tau2_s": 0.037, "delay2_s": 0.028}
    G3, d3 = fitted_plant("yaw-rate-plant", paths)
    assert d3 == pytest.approx(0.026)
    exact = G1(s) * 0.5 * (np.exp(-s * 0.024) + np.exp(-s * 0.028))
    assert np.allclose(np.abs(G3(s) * np.exp(-s * d3)), np.abs(exact) / np.cos(w * 0.002), rtol=1e-9)
    assert fitted_plant("no-such-plant", one) is None
    assert fitted_plant("yaw-rate-plant", {"K": 7.5}) is None
