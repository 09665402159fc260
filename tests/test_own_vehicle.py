"""Own-vehicle twins: generic frames, `rotorlab vehicle new`, the x500 reference twin, per-axis calibration.

Ground truth: PX4's rotor numbering and turning directions (the files cited in rotorlab.vehicles.spec.FRAMES), the
rigid-body torque gain computed by hand from arm, thrust slope and inertia, Newton's law at hover, and the TUHH
twin's true linearisation (rotorlab.sim.linearize) as the calibration target.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from rotorlab import lti
from rotorlab.cli import main
from rotorlab.errors import ConfigError
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator
from rotorlab.vehicles import RHO_AIR, VEHICLES_DIR, load_vehicle, parse_vehicle
from rotorlab.vehicles.fit_axes import calibrate_axes, twin_scene, write_calibrated
from rotorlab.vehicles.spec import FRAMES

# PX4's tables in FRD (x forward, y right) with CW/CCW: 4001_gz_x500 CA_ROTOR0..3 (PX, PY signs; KM > 0 = CCW) and
# geometries/hex_x.toml
PX4 = {
    "quad-x": [((1, 1), "CCW"), ((-1, -1), "CCW"), ((1, -1), "CW"), ((-1, 1), "CW")],
    "hexa-x": [((0.0, 1.0), "CW"), ((0.0, -1.0), "CCW"), ((0.866025, -0.5), "CW"), ((-0.866025, 0.5), "CCW"),
               ((0.866025, 0.5), "CCW"), ((-0.866025, -0.5), "CW")],
}
# moment arm of one % of axis command by hand: the mixer's half command on each rotor of the axis, times its distance
LEVER = {"quad-plus": (1.0, 1.0), "quad-x": (math.sqrt(2.0), math.sqrt(2.0)), "hexa-x": (1.5, math.sqrt(3.0))}


@pytest.mark.parametrize("frame", sorted(PX4))
def test_frames_follow_px4_numbering_and_turning_directions(frame):
    dirs, spins = FRAMES[frame]
    for (d, s), ((px, py), turn) in zip(zip(dirs, spins, strict=True), PX4[frame], strict=True):
        unit = np.array([px, py]) / np.hypot(px, py)
        assert np.allclose([d[0], -d[1]], unit, atol=1e-6)  # FLU -> FRD
        assert s == (1.0 if turn == "CW" else -1.0)


def test_quad_plus_is_the_default_layout():
    data = tomllib.loads((VEHICLES_DIR / "tuhh-quad" / "vehicle.toml").read_text())
    assert "frame" not in data["airframe"]
    v = parse_vehicle(data, "tuhh.toml")
    l, h = v.arm_m, v.rotor_height_m
    assert v.frame == "quad-plus"
    assert np.array_equal(v.rotor_positions(), np.array([[l, 0, h], [0, -l, h], [-l, 0, h], [0, l, h]]))


def _new(tmp_path, frame, *extra):
    out = tmp_path / f"{frame}.toml"
    assert main(["vehicle", "new", f"my-{frame}", "--frame", frame, "--mass-kg", "1.6", "--arm-m", "0.25",
                 "--prop-in", "10", *extra, "--out", str(out)]) == 0
    return load_vehicle(out)


@pytest.mark.parametrize("frame", sorted(FRAMES))
def test_vehicle_new_hovers_at_its_hover_command(tmp_path, frame):
    v = _new(tmp_path, frame, "--kv", "800", "--cells", "4")
    assert v.frame == frame and v.n_rotors == len(FRAMES[frame][1])
    text = v.path.read_text()
    for key in ("inertia_kgm2", "thrust_coefficient", "speed_map", "hover_command", "lag_s", "delay_s"):
        line = next(ln for ln in text.splitlines() if ln.startswith(key))
        assert "#" in line, line  # every number says where it comes from
    sim = Simulator("free-flight", v, sensor_noise=False)
    z0 = float(sim.data.qpos[2])
    sim.set_rotor_commands([100.0 * v.rotor.hover_command] * v.n_rotors)
    for _ in range(round(1.0 / sim.control_dt_s)):
        sim.tick()
    # 0.1 % of weight left over would move it 5 mm in 1 s
    assert abs(sim.data.qpos[2] - z0) < 1e-3 and np.max(np.abs(sim.data.qvel[:6])) < 1e-3
    assert max(abs(a) for a in sim.true_attitude_deg()) < 1e-3


def _hand_rate_gain(v, axis):
    """b of b / s, deg/s^2 per % of axis command, from the file's numbers (linear ESC map or TUHH's)."""
    r = v.rotor
    k_T = r.thrust_coefficient * RHO_AIR * math.pi * r.radius_m**4
    a0, a1, a2 = r.speed_map
    b = r.hover_command
    omega = a0 * b**a1 + a2
    dT_pct = k_T * 2.0 * omega * a0 * a1 * b ** (a1 - 1.0) / 100.0  # N per % per rotor
    if axis == "yaw":
        moment = v.n_rotors * 0.5 * r.torque_to_thrust_m * dT_pct
    else:
        moment = LEVER[v.frame][0 if axis == "roll" else 1] * v.arm_m * dT_pct
    return moment / v.inertia_kgm2["xyz".index({"roll": "x", "pitch": "y", "yaw": "z"}[axis])] * 180.0 / math.pi


@pytest.mark.parametrize("frame", [*sorted(FRAMES), "x500"])
def test_linearisation_has_the_hand_torque_gain(tmp_path, frame):
    v = load_vehicle("x500") if frame == "x500" else _new(tmp_path, frame)
    axes = ("roll", "pitch") if v.rotor.inertia_kgm2 else ("roll", "pitch", "yaw")  # J_R adds a yaw zero
    G = linearize("free-flight", v, list(axes), [f"gyro_{a}" for a in axes], delay=False)
    w = 10.0  # well above the free-flight modes, below the IMU mount
    tau = v.rotor.lag_s[0]
    H = lti.freqresp(G, np.array([w]))[0]
    for i, axis in enumerate(axes):
        b = H[i, i] * 1j * w * (1.0 + 1j * w * tau)  # b / s behind the motor lag -> b
        assert abs(b) == pytest.approx(_hand_rate_gain(v, axis), rel=0.01), axis
        assert abs(np.degrees(np.angle(b))) < 2.0, axis


def test_x500_holds_position_with_its_baseline_gains():
    # "none" is how the CLI says no gain switch (a TOML option value cannot be None); the x500 has one gain set
    r = run_scenario("hover", "x500", seed=1, duration_s=4.0, options={"switch_s": "none"})
    assert r.info.get("stopped") is None
    half = len(r.log["t"]) // 2
    assert np.max(np.abs(r.log["x"][half:])) < 0.3 and np.max(np.abs(r.log["y"][half:])) < 0.3
    assert np.max(np.abs(r.log["theta"][half:])) < 5.0 and abs(r.log["z"][-1] - r.log["z_ref"][-1]) < 0.1
    with pytest.raises(ConfigError, match="options.switch_s"):
        run_scenario("hover", "x500", duration_s=1.0, options={"switch_s": "never"})


@pytest.mark.parametrize("options, field, rule", [
    ({"--mass-kg": ["-1"]}, "mass_kg", "expected a finite number > 0"),
    ({"--kv": ["300"], "--cells": ["2"]}, "kv", "cannot lift"),
    ({"--inertia": ["0.01", "0.01", "0.05"]}, "airframe.inertia_kgm2", "I_a + I_b >= I_c"),
    ({"--inertia": ["0.01", "-0.01", "0.05"]}, "inertia_kgm2", "> 0"),
    ({"--prop-in": ["30"]}, "prop_in", "overlap"),
])
def test_vehicle_new_refuses_bad_numbers(tmp_path, capsys, options, field, rule):
    given = {"--mass-kg": ["1.6"], "--arm-m": ["0.25"], "--prop-in": ["10"], **options}
    argv = ["vehicle", "new", "bad", "--frame", "quad-x", *[x for k, vals in given.items() for x in (k, *vals)],
            "--out", str(tmp_path / "bad.toml")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"field '{field}'" in err and rule in err and "Traceback" not in err
    assert not (tmp_path / "bad.toml").exists()


@pytest.mark.parametrize("edit, field, rule", [
    (("hover_command = 0.7289", "hover_command = 0.6"), "rotor.hover_command", "hold the weight"),
    (("speed_map = [850.0, 1.0, 150.0]", "speed_map = [300.0, 1.0, 150.0]"), "rotor.speed_map", "cannot lift"),
    (("lag_s = 0.01875", "lag_s = [0.02, 0.02, 0.02]"), "rotor.lag_s", None),
    (("frame = \"quad-x\"", "frame = \"octo-x\""), "airframe.frame", None),
])
def test_vehicle_file_refuses_non_physical_numbers(tmp_path, edit, field, rule):
    text = (VEHICLES_DIR / "x500" / "vehicle.toml").read_text()
    assert edit[0] in text
    with pytest.raises(ConfigError) as exc:
        parse_vehicle(tomllib.loads(text.replace(edit[0], edit[1])), "x500.toml")
    assert f"field '{field}'" in str(exc.value) and (rule is None or rule in str(exc.value))


def test_calibration_recovers_tuhh_quad_from_30_percent_off(tmp_path):
    """The issue's acceptance point with LTI targets: a generic plus quad with the TUHH mass, geometry and rotor
    but inertia and motor pole 30 % off (and a wrong delay) is calibrated to the TUHH twin's true free-flight
    linearisations; its response must be within 1 dB and 5 deg over 1-30 rad/s."""
    truth = load_vehicle("tuhh-quad")
    targets = _tuhh_targets(truth)
    r = truth.rotor
    J = truth.inertia_kgm2
    start = dataclasses.replace(
        truth, inertia_kgm2=(1.3 * J[0], 0.7 * J[1], 1.3 * J[2]), rigs={}, published={},
        rotor=dataclasses.replace(r, lag_s=tuple(lag / 0.7 for lag in r.lag_s), delay_s=(0.015,) * 4))
    c = calibrate_axes(start, targets)
    assert max(s.max_db for s in c.residual_start.values()) > 3.0  # the start is visibly wrong
    for axis, res in c.residual.items():
        assert res.w_rad_s[0] == pytest.approx(1.0) and res.w_rad_s[-1] == pytest.approx(30.0)
        assert res.max_db < 1.0 and res.max_deg < 5.0, axis
    # the physical parameters come back, not just the response
    assert c.inertia_kgm2 == pytest.approx(J, rel=0.02)
    assert c.lag_s == pytest.approx(r.lag_s, rel=0.02) and c.delay_s == pytest.approx(r.delay_s, abs=1e-9)
    assert c.rotor_inertia_kgm2 == pytest.approx(r.inertia_kgm2, rel=0.02) and c.at_bounds == ()
    assert c.hforce_N_per_mps == pytest.approx(r.hforce_N_per_mps, rel=0.02)
    out = write_calibrated(truth.path, c, tmp_path / "calibrated.toml")
    back = load_vehicle(out)
    assert back.inertia_kgm2 == c.inertia_kgm2 and back.rotor.lag_s == c.lag_s
    assert "calibrated" in next(ln for ln in out.read_text().splitlines() if ln.startswith("inertia_kgm2"))


def test_vehicle_calibrate_cli_fits_model_files(tmp_path, capsys):
    """rotorlab vehicle calibrate with model JSON files (as rotorlab ident writes them): delay-free models plus their
    delay, roll and pitch only; yaw's inertia is not fitted and stays as it was."""
    from rotorlab.ident.modelio import save_model

    truth = load_vehicle("tuhh-quad")
    argv = ["vehicle", "calibrate"]
    for axis, delay_s in (("roll", 0.024), ("pitch", 0.028)):
        path = tmp_path / f"{axis}.json"
        save_model(path, linearize(twin_scene(truth), truth, axis, f"gyro_{axis}", delay=False), delay_s=delay_s)
        argv += ["--model", f"{axis}={path}"]
    text = (VEHICLES_DIR / "tuhh-quad" / "vehicle.toml").read_text().split("[rig.pitch]")[0]
    start = tmp_path / "start.toml"
    start.write_text(text.replace("inertia_kgm2 = [0.0181, 0.0196, 0.0273]", "inertia_kgm2 = [0.013, 0.026, 0.03]"))
    out = tmp_path / "cal.toml"
    assert main([*argv, str(start), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "roll: max" in printed and "w rad/s" in printed
    v = load_vehicle(out)
    assert v.inertia_kgm2[:2] == pytest.approx(truth.inertia_kgm2[:2], rel=0.02) and v.inertia_kgm2[2] == 0.03
    assert main(["vehicle", "calibrate", str(start), "--model", "pitch", "--out", str(out)]) == 2


def _tuhh_targets(truth):
    """The TUHH twin's true rate responses per axis on the gimbal (rotation about the CG), delays included."""
    return {a: linearize(twin_scene(truth), truth, a, f"gyro_{a}") for a in ("roll", "pitch", "yaw")}


def _tuhh_thrust_stand(tmp_path, tuhh):
    """A thrust-stand sweep CSV generated from the TUHH rotor (ref. 002 eqs. 3-5)."""
    r = tuhh.rotor
    b = np.linspace(0.1, 1.0, 19)
    w = r.speed(b)
    k_T = r.thrust_coefficient * RHO_AIR * math.pi * r.radius_m**4
    k_Q = r.torque_coefficient * RHO_AIR * math.pi * r.radius_m**5
    csv = tmp_path / "stand.csv"
    csv.write_text("command,speed_rad_s,thrust_N,torque_Nm\n"
                   + "".join(f"{x!r},{y!r},{k_T * y * y!r},{k_Q * y * y!r}\n"
                             for x, y in zip(b.tolist(), w.tolist(), strict=True)))
    return csv


def _tuhh_from_stand(tmp_path, tuhh, *extra):
    out = tmp_path / "stand.toml"
    assert main(["vehicle", "new", "stand", "--frame", "quad-plus", "--mass-kg", str(tuhh.mass_kg), "--arm-m",
                 str(tuhh.arm_m), "--prop-in", str(2 * tuhh.rotor.radius_m / 0.0254), *extra,
                 "--thrust-stand", str(_tuhh_thrust_stand(tmp_path, tuhh)), "--out", str(out)]) == 0
    return load_vehicle(out)


def test_vehicle_new_fits_a_thrust_stand_table(tmp_path):
    """The TUHH rotor's thrust-stand sweep gives back its C_T, C_Q, speed map and hover command, and the twin's
    pitch torque gain equals the TUHH twin's."""
    tuhh = load_vehicle("tuhh-quad")
    r = tuhh.rotor
    v = _tuhh_from_stand(tmp_path, tuhh, "--inertia", *map(str, tuhh.inertia_kgm2))
    assert v.rotor.thrust_coefficient == pytest.approx(r.thrust_coefficient, rel=1e-9)
    assert v.rotor.torque_coefficient == pytest.approx(r.torque_coefficient, rel=1e-9)
    assert v.rotor.speed_map == pytest.approx(r.speed_map, rel=1e-5)
    assert v.rotor.hover_command == pytest.approx(r.hover_command, rel=1e-4)
    assert _hand_rate_gain(v, "pitch") == pytest.approx(_hand_rate_gain(tuhh, "pitch"), rel=1e-4)
    # a table and kv/cells are two sources of the same numbers
    assert main(["vehicle", "new", "stand", "--frame", "quad-plus", "--mass-kg", "1", "--arm-m", "0.2",
                 "--prop-in", "10", "--kv", "900", "--cells", "3", "--thrust-stand", str(tmp_path / "stand.csv"),
                 "--out", str(tmp_path / "both.toml")]) == 2


def test_calibration_from_vehicle_new_and_a_thrust_stand(tmp_path):
    """The whole own-vehicle path with LTI targets: vehicle new from the TUHH mass, arm, propeller and its
    thrust-stand sweep, everything else estimated (geometric inertia 24-46 % low, motor 30 ms, delay 10 ms, no rotor
    inertia or in-plane drag, another IMU mount), calibrated to the TUHH twin's per-axis responses: within 1 dB and
    5 deg over 1-30 rad/s, and the physical parameters back."""
    tuhh = load_vehicle("tuhh-quad")
    start = _tuhh_from_stand(tmp_path, tuhh)
    c = calibrate_axes(start, _tuhh_targets(tuhh))
    assert min(s.max_deg for s in c.residual_start.values()) > 25.0
    assert c.max_error_db < 1.0 and c.max_error_deg < 5.0
    assert c.inertia_kgm2 == pytest.approx(tuhh.inertia_kgm2, rel=0.02)
    assert c.delay_s == pytest.approx(tuhh.rotor.delay_s, abs=1e-9)
    assert c.rotor_inertia_kgm2 == pytest.approx(tuhh.rotor.inertia_kgm2, rel=0.05)


def test_calibration_of_a_quad_x_shares_one_motor_pole_and_delay():
    """quad-x: every rotor drives roll and pitch, so one motor pole and one delay are fitted (to the x500's own
    responses, from inertia and pole 30 % off and 15 ms of delay against its 0); a non-physical start is refused."""
    x500 = load_vehicle("x500")
    r = x500.rotor
    targets = {a: linearize(twin_scene(x500), x500, a, f"gyro_{a}") for a in ("roll", "pitch", "yaw")}
    start = dataclasses.replace(x500, inertia_kgm2=tuple(1.3 * j for j in x500.inertia_kgm2),
                                rotor=dataclasses.replace(r, lag_s=(r.lag_s[0] / 0.7,) * 4, delay_s=(0.015,) * 4))
    c = calibrate_axes(start, targets)
    assert len(set(c.lag_s)) == 1 and len(set(c.delay_s)) == 1
    assert c.at_bounds == ("delay all rotors at its lower bound",)  # the x500 model has no delay
    assert c.max_error_db < 1.0 and c.max_error_deg < 5.0
    assert c.inertia_kgm2 == pytest.approx(x500.inertia_kgm2, rel=0.02)
    flat = dataclasses.replace(start, inertia_kgm2=(0.01, 0.01, 0.03))
    with pytest.raises(ConfigError, match="I_a \\+ I_b >= I_c"):
        calibrate_axes(flat, targets)


def test_own_vehicle_without_gain_sets_flies_an_autopilot_and_refuses_the_cascade(tmp_path):
    """A vehicle file with no gain set beside it (``vehicle new``, a calibrated twin): with PX4's laws flying the
    attitude the cascade's gains are never read, so the run flies (and holds its hover); the built-in cascade
    itself still needs a set and is refused with the field named."""
    from rotorlab.sim.control.autopilot import AutopilotSpec

    own = tmp_path / "own.toml"
    own.write_text((VEHICLES_DIR / "x500" / "vehicle.toml").read_text().replace('name = "x500"', 'name = "own"', 1))
    r = run_scenario("rest", str(own), scene="free-flight", duration_s=3.0, controller=AutopilotSpec.from_params("px4"))
    assert r.stopped is None
    assert max(abs(r.log["phi"]).max(), abs(r.log["theta"]).max()) < 1.0  # deg: the autopilot holds it level
    with pytest.raises(ConfigError) as exc:
        run_scenario("rest", str(own), scene="free-flight", duration_s=1.0)
    assert "gains" in str(exc.value)


def test_calibration_with_the_motors_held_fits_only_the_rest():
    """``fit_motors=False`` keeps the start's lags and delays exactly and fits the inertias (and yaw's rotor terms)
    alone: from the true motors and inertias 30 % off, the inertias come back."""
    truth = load_vehicle("tuhh-quad")
    J = truth.inertia_kgm2
    start = dataclasses.replace(truth, inertia_kgm2=(1.3 * J[0], 0.7 * J[1], 1.3 * J[2]), rigs={}, published={})
    c = calibrate_axes(start, _tuhh_targets(truth), fit_motors=False)
    assert c.lag_s == truth.rotor.lag_s and c.delay_s == truth.rotor.delay_s
    assert c.inertia_kgm2 == pytest.approx(J, rel=0.02)
    assert max(r.max_db for r in c.residual.values()) < 0.1
