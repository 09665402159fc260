"""Sensors (rotorlab.sim.sensors): the registry, each sensor's reading against the MuJoCo state it measures,
the seeded noise stream, and the command limits read from the vehicle TOML."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from helpers import ELEMENTARY_ULPS, assert_within_ulps, classes_defined_in, snake_case
from scipy.spatial.transform import Rotation

from rotorlab.errors import ConfigError
from rotorlab.scenes import PREFIX
from rotorlab.sim import sensors as sensors_pkg
from rotorlab.sim.batch import run_batch
from rotorlab.sim.frames import RAD2DEG
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.sensors import IMU, SENSORS, Sensor
from rotorlab.sim.simulator import Simulator
from rotorlab.vehicles import load_vehicle, vehicle_path

G = 9.81


def _moving_free_flight(seed=0):
    """A free-flight state with a tilted attitude and a body rate (noise off), all stages computed."""
    sim = Simulator("free-flight", "anteos-p2a2", sensor_noise=False, seed=seed)
    d = sim.data
    d.qpos[3:7] = Rotation.from_euler("ZYX", [0.4, -0.2, 0.3]).as_quat(scalar_first=True)
    d.qvel[3:6] = [0.5, -0.8, 0.3]  # rad/s, body FLU
    mujoco.mj_forward(sim.model, d)
    return sim


def _site(sim, name="imu"):
    return mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_SITE, f"{PREFIX}{name}")


def test_registry_holds_every_sensor_in_a_file_named_after_it():
    defined = set()
    for module, obj in classes_defined_in(sensors_pkg, Sensor):
        defined.add(obj)
        assert module == snake_case(obj.__name__), (module, obj.__name__)
    assert defined == set(SENSORS.values())
    assert all(cls.name == name for name, cls in SENSORS.items())
    # every registered sensor is exercised against MuJoCo below
    assert set(SENSORS) == {"imu-gyro", "imu-attitude", "imu-accelerometer", "load-cell", "tachometer"}


def test_gyro_reads_the_imu_site_angular_velocity_in_frd():
    sim = _moving_free_flight()
    v6 = np.zeros(6)
    mujoco.mj_objectVelocity(sim.model, sim.data, mujoco.mjtObj.mjOBJ_SITE, _site(sim), v6, 1)  # local frame
    expected = np.array([v6[0], -v6[1], -v6[2]]) * RAD2DEG
    np.testing.assert_allclose(SENSORS["imu-gyro"](sim.model, sim.vehicle).read(sim.data.sensordata), expected,
                               rtol=0, atol=1e-9)
    m = sim.measure()
    np.testing.assert_allclose([m["p"], m["q"], m["r"]], expected, rtol=0, atol=1e-9)
    assert abs(expected[1]) > 40.0  # the state really rotates (0.8 rad/s nose down: q = +45.8 deg/s)


def test_attitude_reads_the_imu_site_orientation_as_aerospace_angles():
    sim = _moving_free_flight()
    yaw, pitch, roll = Rotation.from_matrix(sim.data.site_xmat[_site(sim)].reshape(3, 3)).as_euler("ZYX")
    # FLU/z-up to aerospace: roll kept, pitch and yaw change sign (nose up and nose right positive)
    expected = np.degrees([roll, -pitch, -yaw])
    np.testing.assert_allclose(SENSORS["imu-attitude"](sim.model, sim.vehicle).read(sim.data.sensordata), expected,
                               rtol=0, atol=1e-9)
    m = sim.measure()
    np.testing.assert_allclose([m["phi"], m["theta"], m["psi"]], expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(expected, np.degrees([0.3, 0.2, -0.4]), atol=0.5)  # the imposed attitude


def test_accelerometer_reads_specific_force_in_frd():
    sim = _moving_free_flight()
    a6 = np.zeros(6)
    mujoco.mj_objectAcceleration(sim.model, sim.data, mujoco.mjtObj.mjOBJ_SITE, _site(sim), a6, 1)
    expected = a6[3:6] * np.array([1.0, -1.0, -1.0])
    np.testing.assert_allclose(SENSORS["imu-accelerometer"](sim.model, sim.vehicle).read(sim.data.sensordata),
                               expected, rtol=0, atol=1e-9)
    # physics anchor: level on the rig at the hover trim the IMU feels 1 g upwards, i.e. az = -g in FRD
    rig = Simulator("pitch-rig", "anteos-p2a2", sensor_noise=False)
    m = rig.measure()
    np.testing.assert_allclose([m["ax"], m["ay"], m["az"]], [0.0, 0.0, -G], atol=0.05)


@pytest.mark.parametrize("vehicle", ["tuhh-quad", "anteos-p2a2"])
def test_load_cell_and_tachometer_read_the_rotor(vehicle):
    sim = Simulator("thrust-stand", vehicle, sensor_noise=False)
    v = sim.vehicle
    sim.set_rotor_commands([70.0])
    for _ in range(150):  # 3 s: the motor / servo has settled, the cell's spring is at rest
        sim.tick()
    thrust, torque = sim.load_cell()
    rotor_force = float(sim.data.actuator_force[sim.scene.thrust_actuators[0]])
    assert thrust == pytest.approx(rotor_force, rel=2e-3)
    assert abs(torque) == pytest.approx(v.rotor.torque_to_thrust_m * rotor_force, rel=0.02) \
        if v.kind == "variable-pitch" else abs(torque) > 0.0
    omega = sim.rotor_speed_rad_s()
    if v.kind == "variable-rpm":
        act = sim.data.act[sim.model.actuator_actadr[sim.scene.thrust_actuators[0]]]
        assert omega[0] == pytest.approx(math.sqrt(act), rel=1e-12)
        assert omega[0] == pytest.approx(float(v.rotor.speed(0.7)), rel=1e-3)
    else:
        assert omega[0] == v.rotor.rotor_speed_rad_s
    # the rig and free-flight models carry no load cell: the sensor is simply absent there
    assert "load-cell" not in Simulator("pitch-rig", vehicle, sensor_noise=False).sensors


@pytest.mark.parametrize("scene", ["free-flight", "thrust-stand"])
def test_every_sensor_declares_whether_it_reads_acceleration_stage_data(scene):
    """Sensor.acceleration_stage (which lets the simulator skip the tick's acceleration pass when nothing reads
    the sensor) says the truth for every registered sensor: with MuJoCo's acceleration-stage sensordata
    (sensor_needstage) replaced by NaN, a sensor's readings are NaN exactly when it declares the stage."""
    sim = Simulator(scene, "anteos-p2a2", sensor_noise=False)
    m = sim.model
    x = sim.data.sensordata.copy()
    for i in range(m.nsensor):
        if m.sensor_needstage[i] == mujoco.mjtStage.mjSTAGE_ACC:
            x[m.sensor_adr[i]: m.sensor_adr[i] + m.sensor_dim[i]] = np.nan
    assert np.isnan(x).any() == (scene == "free-flight")  # the accelerometer is there; the stand's cell is not one
    walked = 0
    for name, cls in SENSORS.items():
        if cls.field != "sensordata" or name not in sim.sensors:
            continue
        walked += 1
        assert np.isnan(sim.sensors[name].read(x)).any() == cls.acceleration_stage, name
    assert walked == (3 if scene == "free-flight" else 1)


@pytest.mark.parametrize("vehicle", ["tuhh-quad", "anteos-p2a2"])
def test_every_sensor_reads_one_simulation_as_floats_bit_for_bit(vehicle):
    """The simulator's per-tick path (Sensor.read_floats, SensorSuite.sample of one simulation) gives the floats
    of the vectorised read the batched runner uses, within the contract's bounds for two code paths
    (docs/reproducibility.md: numpy's SIMD atan2/asin against the C library's); each path run twice gives the
    same floats bit for bit."""
    free = _moving_free_flight()
    stand = Simulator("thrust-stand", vehicle, sensor_noise=False)
    stand.set_rotor_commands([70.0])
    for _ in range(5):
        stand.tick()
    seen = set()
    for sim in (free, stand):
        for name, sensor in sim.sensors.items():
            x = getattr(sim.data, sensor.field)
            got = sensor.read_floats(x.tolist())
            assert all(type(v) is float for v in got), name
            assert got == sensor.read_floats(x.tolist()), name  # one path, twice
            assert np.array_equal(np.array(got), sensor.read(x)), name  # one simulation's read is this path
            many = sensor.read(np.repeat(x[None, :], 3, axis=0))
            assert np.array_equal(many, sensor.read(np.repeat(x[None, :], 3, axis=0))), name
            assert_within_ulps(got, many[0], err_msg=name)
            seen.add(name)
    assert seen == set(SENSORS)
    noisy = Simulator("free-flight", vehicle, seed=3)
    rows = np.repeat(noisy.data.sensordata[None, :], 2, axis=0)
    gens = [np.random.default_rng(3) for _ in range(2)]  # as Simulator.reset seeds its own: bias, then ticks
    batch_noise = noisy.imu.noise(gens, np.array([noisy.imu.draw_bias(g) for g in gens]))
    one, many = noisy.imu.sample(noisy.data.sensordata, noisy._noise), noisy.imu.sample(rows, batch_noise)
    assert all(type(v) is float for v in one.values())
    twin = Simulator("free-flight", vehicle, seed=3)
    assert one == twin.imu.sample(twin.data.sensordata, twin._noise)  # one path, twice
    # the same noise on readings that may differ by the two paths' bound: each sum rounds once more
    clean = noisy.imu.read(rows)[0]
    for j, c in enumerate(noisy.imu.channels):
        allowed = ELEMENTARY_ULPS * np.spacing(abs(clean[j])) + np.spacing(abs(one[c]))
        assert abs(one[c] - many[c][0]) <= allowed, f"the scalar and the batched noisy sample differ in {c}"


def test_noise_stream_is_bias_then_one_draw_per_tick_in_imu_order():
    seed = 17
    noisy = Simulator("pitch-rig", "anteos-p2a2", seed=seed, sensor_noise=True)
    clean = Simulator("pitch-rig", "anteos-p2a2", seed=seed, sensor_noise=False)
    imu = load_vehicle("anteos-p2a2").imu
    rng = np.random.default_rng(seed)
    bias = np.concatenate([rng.normal(0.0, imu.gyro_bias_dps, 3), np.zeros(6)])
    std = np.repeat([imu.gyro_noise_dps, imu.angle_noise_deg, imu.accel_noise_mps2], 3)
    order = [c for cls in IMU for c in cls.channels]
    assert order == ["p", "q", "r", "phi", "theta", "psi", "ax", "ay", "az"]
    for _ in range(3):
        a, b = noisy.measure(), clean.measure()
        expected = bias + std * rng.standard_normal(9)
        np.testing.assert_allclose([a[c] - b[c] for c in order], expected, rtol=0, atol=1e-9)
        noisy.tick()
        clean.tick()


def _vehicle_with_commands(tmp_path, block):
    text = vehicle_path("anteos-p2a2").read_text()
    i = text.index("[commands]")
    j = text.index("\n\n", i)
    p = tmp_path / "vehicle.toml"
    p.write_text(text[:i] + block + text[j:])
    return p


def test_command_limits_are_read_strictly_from_the_vehicle_toml(tmp_path):
    v = load_vehicle(_vehicle_with_commands(tmp_path, "[commands]\nlimit_pct = 12.0\nrate_limit_dps = 40.0\n"
                                                       "yaw_limit_pct = 7.0\nyaw_rate_limit_dps = 25.0"))
    assert dataclasses.astuple(v.commands) == (12.0, 40.0, 7.0, 25.0) and v.command_limit_pct == 12.0
    with pytest.raises(ConfigError, match=r"commands.rate_limit_dpss.*one of"):
        load_vehicle(_vehicle_with_commands(tmp_path, "[commands]\nlimit_pct = 12.0\nrate_limit_dps = 40.0\n"
                                                      "rate_limit_dpss = 1.0\nyaw_limit_pct = 7.0\n"
                                                      "yaw_rate_limit_dps = 25.0"))
    with pytest.raises(ConfigError, match=r"commands.yaw_limit_pct"):
        load_vehicle(_vehicle_with_commands(tmp_path, "[commands]\nlimit_pct = 12.0\nrate_limit_dps = 40.0\n"
                                                      "yaw_rate_limit_dps = 25.0"))


def test_limits_from_the_toml_clip_the_scalar_and_the_batched_loops(tmp_path):
    v = load_vehicle(_vehicle_with_commands(tmp_path, "[commands]\nlimit_pct = 12.0\nrate_limit_dps = 40.0\n"
                                                       "yaw_limit_pct = 7.0\nyaw_rate_limit_dps = 25.0"))
    opts = {"steps_deg": [10.0], "small_step_deg": 0.0, "hold_s": 1.5}
    r = run_scenario("setpoint", v, duration_s=3.0, options=opts, sensor_noise=False)
    b = run_batch("setpoint", v, 1, duration_s=3.0, options=opts, sensor_noise=False).log(0)
    for log in (r.log, b):
        u, q_ref = np.abs(log["u_lon"]), np.abs(log["q_ref"])
        # a 10 deg step asks for ~90 deg/s and ~100 %: both saturate, exactly at the TOML's values
        assert u.max() == pytest.approx(12.0, abs=1e-12) and q_ref.max() == pytest.approx(40.0, abs=1e-12)
        assert np.abs(log["u_yaw"]).max() <= 7.0
