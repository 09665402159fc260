"""Headless runs, logs, determinism, CLI, and bad input of the simulation core."""

import json
import math

import mujoco
import numpy as np
import pyarrow.parquet as pq
import pytest
from helpers import assert_sums_agree

from rotorlab.cli import main
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.scenes import build_scene
from rotorlab.sim.control.statespace import ControllerSpec
from rotorlab.sim.disturbances import DrydenWind, InputDisturbanceStep, MeanWind, RecirculationMoment, RopePull
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator, air_motion_map, body_wind, set_air_motion, set_wind
from rotorlab.vehicles import load_vehicle, vehicle_path


def _arrays(path):
    t = pq.read_table(path)
    return {c: np.asarray(t[c]) for c in t.column_names}


def test_same_seed_bit_identical_log(tmp_path):
    a = run_scenario("rest", "anteos-p2a2", scene="free-flight", duration_s=2.0, seed=7, out=tmp_path / "a")
    b = run_scenario("rest", "anteos-p2a2", scene="free-flight", duration_s=2.0, seed=7, out=tmp_path / "b")
    c = run_scenario("rest", "anteos-p2a2", scene="free-flight", duration_s=2.0, seed=8, out=tmp_path / "c")
    la, lb, lc = (_arrays(r.out_dir / "log.parquet") for r in (a, b, c))
    for col in la:
        assert np.array_equal(la[col], lb[col], equal_nan=True), col
    assert not np.array_equal(la["q"], lc["q"])


def test_log_has_units_and_run_json(tmp_path):
    r = run_scenario("rest", "anteos-p2a2", duration_s=1.0, out=tmp_path)
    md = pq.read_schema(tmp_path / "log.parquet").metadata
    units = json.loads(md[b"units"])
    assert units["t"] == "s" and units["theta"] == "deg" and units["q"] == "deg/s" and units["u_lon"] == "%"
    info = json.loads((tmp_path / "run.json").read_text())
    assert info["scenario"] == "rest" and info["vehicle"] == "anteos-p2a2" and info["seed"] == 0
    assert info["versions"]["mujoco"] and info["rows"] == 50
    assert r.stopped is None


def test_noise_is_seeded_and_switchable():
    noisy = run_scenario("rest", "anteos-p2a2", duration_s=1.0, seed=1)
    quiet = run_scenario("rest", "anteos-p2a2", duration_s=1.0, seed=1, sensor_noise=False)
    v = load_vehicle("anteos-p2a2")
    std = np.std(noisy.log["q"] - noisy.log["q_true"])
    assert std == pytest.approx(v.imu.gyro_noise_dps, rel=0.3)
    assert np.max(np.abs(quiet.log["q"])) < 1e-9


def test_unknown_names_list_valid_ones():
    with pytest.raises(UnknownNameError, match="anteos-p2a2"):
        load_vehicle("p2a2")
    with pytest.raises(UnknownNameError, match="pitch-rig"):
        build_scene("gimbal", "anteos-p2a2")
    with pytest.raises(UnknownNameError, match="rest"):
        run_scenario("nothing", "anteos-p2a2")


def _broken_vehicle(tmp_path, old, new):
    text = vehicle_path("anteos-p2a2").read_text().replace(old, new)
    assert text != vehicle_path("anteos-p2a2").read_text()
    p = tmp_path / "vehicle.toml"
    p.write_text(text)
    return p


def test_negative_mass_names_file_field_expected_got(tmp_path):
    p = _broken_vehicle(tmp_path, "mass_kg = 5.0", "mass_kg = -5.0")
    with pytest.raises(ConfigError) as exc:
        load_vehicle(p)
    msg = str(exc.value)
    assert str(p) in msg and "airframe.mass_kg" in msg and "[0.001, 1000.0]" in msg and "-5.0" in msg


def test_missing_field_is_named(tmp_path):
    p = _broken_vehicle(tmp_path, "arm_m = 0.415", "")
    with pytest.raises(ConfigError, match="airframe.arm_m"):
        load_vehicle(p)


def test_delay_not_multiple_of_physics_step(tmp_path):
    p = _broken_vehicle(tmp_path, "delay_s = 0.06 ", "delay_s = 0.0605 ")
    with pytest.raises(ConfigError, match=r"rotor.delay_s.*multiple of the physics step"):
        build_scene("pitch-rig", p)


def test_diverging_run_stops_and_keeps_log(tmp_path):
    gains = tmp_path / "unstable.toml"
    # positive feedback on the rate loop: the airframe runs away to the rig stop
    gains.write_text("[pitch.outer]\nkp = 9.26\nkd = 1.11\ntf = 0.03\n[pitch.inner]\nkp = -2.0\nki = 0.0\n")
    r = run_scenario("rest", "anteos-p2a2", scene="free-flight", duration_s=20.0, gains=gains, out=tmp_path / "run")
    assert r.stopped and "tilt" in r.stopped
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    assert info["stopped"] == r.stopped
    rows = pq.read_table(tmp_path / "run" / "log.parquet").num_rows
    assert 0 < rows < 1000


def _plain_mujoco_tick(sim) -> None:
    """The reference tick: the disturbances' update, then MuJoCo's plain steps with every stage and sensor
    computed in every step, then a forward pass at the tick."""
    m, d = sim.model, sim.data
    d.xfrc_applied[:] = 0.0
    sim.wind_world[:] = 0.0
    sim.air_rate_world[:] = 0.0
    for dist in sim.disturbances:
        dist.update(sim, sim.time)
    if sim._airframe >= 0:
        rotates = any(dist.rotates_air for dist in sim.disturbances)
        set_air_motion(m.opt.wind, d.ctrl, d.xmat[sim._airframe], sim.wind_world,
                       sim.air_rate_world if rotates else None, sim._air_map)
    else:
        set_wind(m.opt.wind, d.ctrl, None, sim.wind_world, sim.aero_ids)
    mujoco.mj_step(m, d, nstep=sim.n_substeps)
    mujoco.mj_forward(m, d)


@pytest.mark.parametrize("vehicle, scene, dists", [
    ("anteos-p2a2", "free-flight", lambda: []),
    ("tuhh-quad", "free-flight", lambda: []),
    ("anteos-p2a2", "free-flight", lambda: [MeanWind(3.0, 30.0), DrydenWind(3.0, 5.0, 2.0, 30.0)]),  # stage VEL
    ("tuhh-quad", "pitch-rig", lambda: [RecirculationMoment(0.3, 2.0), InputDisturbanceStep(0.1, 0.3)]),  # ACC
    ("anteos-p2a2", "roll-rig", lambda: [RecirculationMoment(0.3, 2.0), MeanWind(2.0, 80.0)]),  # ACC and VEL
    ("anteos-p2a2", "pitch-rig", lambda: [RopePull(-10.0, 0.2, 0.3, 0.5)]),  # stage POS: the plain step
])
def test_controls_only_tick_is_the_plain_tick_regrouped(vehicle, scene, dists):
    """Simulator.tick, plain and regrouped (controls_only=True, the runner's loop: it reuses the tick's position
    and velocity stages for the next physics step as far as the disturbances' Disturbance.stage allows, and skips
    the sensors between ticks), gives the state, sensors and actuator forces of MuJoCo's plain steps bit for bit
    under changing commands; a bad state still stops the run."""
    ref, plain, fast, lean = (Simulator(scene, vehicle, sensor_noise=False, disturbances=dists()) for _ in range(4))
    # lean: nothing reads the acceleration stage at the tick, which the regrouped tick then skips (the rope's
    # tension sensor keeps it on its rig): the same state and position/velocity-stage sensors, no accelerometer
    lean.forces_at_tick = False
    m = lean.model
    acc = np.zeros(m.nsensordata, bool)
    for i in range(m.nsensor):
        if m.sensor_needstage[i] == mujoco.mjtStage.mjSTAGE_ACC:
            acc[m.sensor_adr[i]: m.sensor_adr[i] + m.sensor_dim[i]] = True
    assert lean._force_sensors == bool(dists() and isinstance(dists()[0], RopePull))
    rng = np.random.default_rng(0)
    for _ in range(40):
        cmd = plain.vehicle.hover_collective_pct + rng.uniform(-3.0, 3.0, 4)
        for sim in (ref, plain, fast, lean):
            sim.set_commands(cmd)
        _plain_mujoco_tick(ref)
        plain.tick()
        fast.tick(controls_only=True)
        lean.tick(controls_only=True)
        for sim in (plain, fast):
            for field in ("qpos", "qvel", "act", "sensordata", "actuator_force", "xquat"):
                assert np.array_equal(getattr(ref.data, field), getattr(sim.data, field)), field
            assert sim.model.opt.disableflags == 0
        for field in ("qpos", "qvel", "act", "xquat"):
            assert np.array_equal(getattr(ref.data, field), getattr(lean.data, field)), field
        assert np.array_equal(ref.data.sensordata[~acc], lean.data.sensordata[~acc])
        if lean.imu is not None:
            got, want = lean.measure(), fast.measure()
            assert all(math.isnan(got[c]) for c in lean.acc_channels) and len(lean.acc_channels) == 3
            assert {k: v for k, v in got.items() if k not in lean.acc_channels} == \
                {k: v for k, v in want.items() if k not in lean.acc_channels}
    assert fast.check() is None and lean.check() is None
    fast.data.qvel[0] = np.nan
    fast.tick(controls_only=True)
    assert "mjWARN_BADQ" in fast.check()


def _wind_terms(ctrl, rows_wind, wind_terms):
    """Per control, the magnitude sum of the body wind component it takes (0 for the others)."""
    terms = np.zeros(len(ctrl))
    for i, comp, *_ in rows_wind:
        terms[i] = wind_terms[comp]
    return terms


def test_air_motion_of_one_simulation_is_the_body_wind_of_many_plus_the_air_rotation():
    """set_air_motion (one simulation, every windy tick, in floats) puts into opt.wind and the rotor aero
    controls what set_wind's array path (the batched runner) and numpy's matrix product body_wind put there, for
    random airframe orientations and winds; with the air's rotation it adds, to every inflow and in-plane
    actuator and as every disc-tilt damper's reference, J_i . (R^T omega) of air_motion_map as numpy computes
    it. Two code paths, so within the contract's bound for sums of products in another order
    (docs/reproducibility.md); each path run twice gives the same floats."""
    sim = Simulator("free-flight", "anteos-p2a2", sensor_noise=False)
    m, d = sim.model, sim.data
    aero, motion = sim.aero_ids, air_motion_map(m, d, sim._airframe, sim.scene.aero_actuators)
    rows_wind, rows_tilt = motion
    assert {i for i, *_ in rows_wind} == set(np.arange(m.nu)[np.r_[aero["hx"], aero["hy"], aero["inflow"]]])
    assert {i for i, *_ in rows_tilt} == set(np.arange(m.nu)[np.r_[aero["tilt_x"], aero["tilt_y"]]])
    rng = np.random.default_rng(3)
    q = rng.standard_normal((200, 4))
    xmat = np.empty((200, 9))
    for k, quat in enumerate(q / np.linalg.norm(q, axis=1, keepdims=True)):
        mujoco.mju_quat2Mat(xmat[k], quat)
    wind, rate = rng.normal(0.0, 4.0, (200, 3)), rng.normal(0.0, 0.5, (200, 3))
    many_ctrl, many_opt = np.zeros((200, m.nu)), np.zeros((200, 3))
    set_wind(many_opt, many_ctrl, xmat, wind, aero)
    again = np.zeros((200, m.nu))
    set_wind(np.zeros((200, 3)), again, xmat, wind, aero)
    assert np.array_equal(again, many_ctrl)  # the batched path, twice
    for k in range(200):
        ctrl, opt = np.zeros(m.nu), np.zeros(3)
        set_air_motion(opt, memoryview(ctrl), memoryview(xmat[k]), wind[k], None, motion)
        ctrl2 = np.zeros(m.nu)
        set_air_motion(np.zeros(3), memoryview(ctrl2), memoryview(xmat[k]), wind[k], None, motion)
        assert np.array_equal(ctrl2, ctrl) and np.array_equal(opt, wind[k])  # the float path, twice
        Rabs = np.abs(xmat[k].reshape(3, 3))
        wind_terms = Rabs.T @ np.abs(wind[k])  # sum |R_ji a_j|: the size the roundings scale with
        assert_sums_agree(ctrl, many_ctrl[k], _wind_terms(ctrl, rows_wind, wind_terms), 3,
                          err_msg=f"set_wind, row {k}")
        wb = body_wind(xmat[k], wind[k])
        assert_sums_agree(ctrl[[2, 3, 1]], wb, wind_terms, 3, err_msg=f"body_wind, row {k}")
        assert_sums_agree(ctrl[[20, 21, 19]], wb, wind_terms, 3, err_msg=f"body_wind, row {k}")
        set_air_motion(opt, ctrl, xmat[k], wind[k], rate[k], motion)
        w = body_wind(xmat[k], rate[k])
        rate_terms = Rabs.T @ np.abs(rate[k])
        expect, terms = many_ctrl[k].copy(), _wind_terms(ctrl, rows_wind, wind_terms)
        for i, _, *J in rows_wind:
            expect[i] += np.dot(J, w)
            terms[i] += np.abs(J) @ rate_terms
        for i, *J in rows_tilt:
            expect[i] = np.dot(J, w)
            terms[i] = np.abs(J) @ rate_terms
        # the longest path: 3 products summed (R^T omega), times J and summed over 3, plus the wind: 7 roundings
        assert_sums_agree(ctrl, expect, terms, 7, err_msg=f"with the air's rotation, row {k}")
    ctrl = np.zeros(m.nu)
    set_wind(opt, ctrl, None, wind[0], aero)  # no airframe: the wind unrotated
    assert np.array_equal(ctrl[[2, 3, 1]], wind[0])


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "tuhh-quad", "x500"])
def test_one_simulations_rotor_ctrl_in_floats_is_the_array_map(vehicle):
    """The float path every tick writes (command_to_ctrl_floats, set_rotor_ctrl of one simulation) gives the
    controls of command_to_ctrl's array path (the batched runner) bit for bit, commands below, inside and above
    the range and NaN included, and set_rotor_ctrl stores them in the thrust actuators and their spin-up twins."""
    v = load_vehicle(vehicle)
    rng = np.random.default_rng(5)
    cmds = rng.uniform(-20.0, 120.0, (500, v.n_rotors))
    cmds[0, 0], cmds[1, :] = math.nan, [0.0, 100.0, -0.0, 50.0][: v.n_rotors] + [1.0] * (v.n_rotors - 4)
    many = v.command_to_ctrl(cmds)
    for k in range(len(cmds)):
        floats = v.command_to_ctrl_floats(cmds[k].tolist())
        assert all(type(c) is float for c in floats)
        np.testing.assert_array_equal(np.array(floats), many[k], strict=True)
    sim = Simulator("free-flight", vehicle, sensor_noise=False)
    sim.set_rotor_commands(cmds[7].tolist())
    ctrl = sim.data.ctrl
    np.testing.assert_array_equal(ctrl[sim.scene.thrust_actuators], many[7])
    if len(sim.scene.spinup_actuators):
        np.testing.assert_array_equal(ctrl[sim.scene.spinup_actuators], many[7])


@pytest.mark.parametrize("vehicle", ["anteos-p2a2", "tuhh-quad"])
def test_rotor_aerodynamics_see_rotation_relative_to_the_air(vehicle):
    """set_air_motion with the air's rotation (the turbulence's gust gradients): every rotor aero actuator
    (inflow, H-force with its flapping moment, hub disc-tilt damping) acts on the motion relative to the air, so a
    vehicle turning with the air feels none of the rotors' damping, and air turning round a still vehicle pushes it
    as hard as the damping resists the opposite turn, at any attitude. The fuselage's own drag (MuJoCo's fluid model, not a rotor
    actuator) is switched off: it sees the uniform wind only."""
    sim = Simulator("free-flight", vehicle, sensor_noise=False)
    m, d = sim.model, sim.data
    m.opt.density = 0.0
    motion = air_motion_map(m, d, sim._airframe, sim.scene.aero_actuators)
    tilt = np.zeros(4)
    mujoco.mju_axisAngle2Quat(tilt, np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2]), 0.35)

    def rot_acc(body_rate, air_rate_body):
        sim.reset(0)
        d.qpos[3:7] = tilt
        d.qvel[3:6] = body_rate  # the free joint's angular velocity is in the airframe's axes
        mujoco.mj_forward(m, d)
        R = d.xmat[sim._airframe].reshape(3, 3)
        set_air_motion(m.opt.wind, d.ctrl, d.xmat[sim._airframe], np.zeros(3), R @ np.asarray(air_rate_body, float),
                       motion)
        mujoco.mj_forward(m, d)
        return d.qacc.copy()  # the airframe's and the hub discs' (the tilt dampers act about the flap hinges)

    rest = rot_acc(np.zeros(3), np.zeros(3))
    for w in ([0.4, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.3]):
        w = np.array(w)
        damped = rot_acc(w, np.zeros(3)) - rest
        assert np.linalg.norm(damped) > 1e-3  # the rotors do damp this turn
        np.testing.assert_allclose(rot_acc(w, w), rest, rtol=0, atol=1e-12 * np.abs(rest).max() + 1e-12)
        np.testing.assert_allclose(rot_acc(np.zeros(3), w) - rest, -damped, rtol=1e-9, atol=1e-12)


def test_runs_skip_the_acceleration_pass_at_the_tick_only_where_nothing_reads_it(monkeypatch):
    """The runner turns Simulator.forces_at_tick off when nothing of the run reads acceleration-stage data: a
    hover in position hold then runs no acceleration pass at its ticks and logs the same floats as the run that
    keeps it for a pose recording (the rotor thrusts); a controller flying on the accelerometer gets the pass
    and finite readings."""
    calls = []
    skip = mujoco.mj_forwardSkip
    monkeypatch.setattr(mujoco, "mj_forwardSkip", lambda *a: (calls.append(a[2]), skip(*a)))
    kw = dict(scene="free-flight", duration_s=2.0, seed=1)
    lean = run_scenario("rest", "anteos-p2a2", **kw)
    assert calls == []
    full = run_scenario("rest", "anteos-p2a2", record_poses=True, **kw)
    assert len(calls) == 100
    assert lean.log.columns == full.log.columns
    for c in lean.log.columns:
        assert np.array_equal(lean.log[c], full.log[c]), c
    calls.clear()
    # u_lon = 0 * az (the cascade keeps the other axes): NaN would reach the rotors if az were not computed
    spec = ControllerSpec(name="on-az", dt_s=0.02, inputs=("az",), outputs=("u_lon",), A=np.zeros((0, 0)),
                          B=np.zeros((0, 1)), C=np.zeros((1, 0)), D=np.zeros((1, 1)))
    r = run_scenario("rest", "anteos-p2a2", controller=spec, **kw)
    assert r.stopped is None and len(calls) == 100 and np.all(r.log["u_lon"] == 0.0)


def test_cli_list_and_run(tmp_path, capsys):
    assert main(["list", "--json"]) == 0
    cat = json.loads(capsys.readouterr().out)
    assert set(cat["vehicles"]) == {"anteos-p2a2", "anteos-a2minib", "tuhh-quad", "x500"}
    assert "free-flight" in cat["scenes"] and "rest" in cat["scenarios"]
    assert main(["run", "rest", "--vehicle", "tuhh-quad", "--duration", "1", "--seed", "3", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "log.parquet").exists() and (tmp_path / "run.json").exists()
    assert main(["run", "rest", "--vehicle", "nope"]) == 2
    assert "valid: anteos-a2minib, anteos-p2a2, tuhh-quad, x500" in capsys.readouterr().err
