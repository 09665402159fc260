"""The autopilots' own laws flown in the twin (sim/control/autopilot.py): the closed loop the tuhh-quad flies at
250 Hz equals the linear analysis of the same laws (rotorlab.autopilots.closed_loop_lti) around the twin's true
linearisation (sim/linearize.py) at the loop rate."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab import autopilots
from rotorlab.designs import resolve_controller
from rotorlab.errors import ConfigError
from rotorlab.sim.control.autopilot import AutopilotController, AutopilotSpec, euler_to_quat, parse_autopilot
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import make_flight_software, resolve_gains, run_scenario
from rotorlab.sim.scenarios import Setup
from rotorlab.sim.simulator import Simulator
from rotorlab.vehicles import load_vehicle

D2R = math.pi / 180
SIGNALS = {"roll": ("phi", "p"), "pitch": ("theta", "q"), "yaw": ("psi", "r")}


def _lifted_plant(v, axis, dt):
    """The twin's linearisation (1 ms, delays included) from the axis command to [rate, angle], held over the
    loop period and sampled at it, in the laws' units: normalised torque in (100 % each), rad/s and rad out."""
    P1 = linearize("free-flight", v, input=axis, output=[f"gyro_{axis}", f"angle_{axis}"])
    n = int(round(dt / P1.dt))
    A1, B1 = np.asarray(P1.A), np.asarray(P1.B)
    A = np.linalg.matrix_power(A1, n)
    B = sum(np.linalg.matrix_power(A1, i) for i in range(n)) @ B1
    return ct.ss(A, B * 100.0, np.asarray(P1.C) * D2R, np.asarray(P1.D) * 100.0 * D2R, dt)


@pytest.mark.parametrize("autopilot, axis, loop, step", [
    ("px4", "roll", "attitude", 1.0), ("px4", "yaw", "attitude", 2.0), ("px4", "pitch", "rate", 5.0),
    ("ardupilot", "pitch", "attitude", 1.0), ("ardupilot", "yaw", "rate", 5.0),
])
def test_the_twin_flies_the_linear_analysis_of_the_autopilot_laws(autopilot, axis, loop, step):
    v = load_vehicle("tuhh-quad")
    spec = AutopilotSpec.from_params(autopilot)
    ang, rate = SIGNALS[axis]
    sim = Simulator("free-flight", v, sensor_noise=False)
    dt = sim.control_dt_s
    t0 = 0.1
    on = lambda t: t >= t0 - 1e-9  # noqa: E731
    if loop == "attitude":
        setup = Setup(mode="cascade", reference=lambda t: {f"{ang}_ref": step if on(t) else 0.0})
        fs = make_flight_software(v, resolve_gains(v, None), setup, dt, controller=spec)
    else:
        setup = Setup(mode="cascade")
        fs = make_flight_software(v, resolve_gains(v, None), setup, dt)
        k = ("roll", "pitch", "yaw").index(axis)
        fs.plugins.append(AutopilotController(spec, dt, fs.u_limit_pct, fs.yaw_u_limit_pct,
                                              rate_reference=lambda t: np.eye(3)[k] * (step if on(t) else 0.0)))
    n = int(round(1.5 / dt))
    sig, got = {}, []
    for _ in range(n):
        t = sim.time
        sim.measure(sig)
        sim.set_rotor_commands(fs.step_signals(t, sig))
        got.append((sig[rate], sig[ang]))
        sim.tick()
    got = np.array(got) - np.array(got[0])
    T = autopilots.closed_loop_lti(autopilot, spec.params, axis, _lifted_plant(v, axis, dt), loop=loop)
    u = np.where(np.arange(n) * dt >= t0 - 1e-9, step * D2R, 0.0)
    A, B, C, D = (np.asarray(M) for M in (T.A, T.B, T.C, T.D))
    x, want = np.zeros(A.shape[0]), []
    for uk in u:
        want.append((C @ x + D[:, 0] * uk)[:2] / D2R)
        x = A @ x + B[:, 0] * uk
    want = np.array(want)
    # rate (deg/s) and angle (deg) within 1.5 % of their peaks: what is left are the twin's nonlinearities
    # (rotor speed map, quaternion attitude error, i_factor) at these small steps
    for j in range(2):
        peak = np.max(np.abs(want[:, j]))
        assert peak > 0.2 * step
        err = np.max(np.abs(got[:, j] - want[:, j]))
        assert err < 0.015 * peak


def test_run_scenario_flies_an_autopilot_and_records_its_parameters():
    spec = AutopilotSpec.from_params("ardupilot", {"ATC_RAT_PIT_P": 0.1}, source="tuned.parm")
    res = run_scenario("setpoint", "tuhh-quad", scene="pitch-rig", controller=spec, duration_s=3.0)
    assert res.stopped is None
    step = res.metrics["steps"][0]
    assert 0.05 < step["rise_time_s"] < 1.0 and abs(step["steady_state_error"]) < 0.02
    c = res.info["controller"][0]
    assert c["name"] == "ardupilot:tuned.parm" and c["params"]["ATC_RAT_PIT_P"] == 0.1
    assert "ATC_RAT_PIT_P" not in c["defaulted"] and "ATC_RAT_RLL_P" in c["defaulted"]
    assert c["dt_s"] == pytest.approx(1 / 250) and c["loop_hz"] == pytest.approx(250.0)
    assert c["params_loop_hz"] == 400.0  # SCHED_LOOP_RATE's default: the twin flies at its own rate, and says so


def test_controller_values_parse_to_autopilots(tmp_path):
    assert resolve_controller("px4:defaults", None).params == autopilots.px4.TABLE.defaults()
    path = tmp_path / "tuned.params"
    autopilots.write_params("px4", path, {"MC_ROLLRATE_P": 0.2}, "tuned")
    spec = resolve_controller(f"px4:{path}", None)
    assert spec.params["MC_ROLLRATE_P"] == 0.2 and spec.source == str(path)
    assert parse_autopilot("betaflight:defaults") is None
    with pytest.raises(ConfigError, match="parameter file not found"):
        parse_autopilot(f"ardupilot:{tmp_path / 'missing.parm'}")


def test_euler_to_quat_is_the_yaw_pitch_roll_rotation():
    phi, theta, psi = 0.3, -0.2, 1.1
    q = euler_to_quat(phi, theta, psi)

    def axis_quat(ax, a):
        v = np.zeros(4)
        v[0], v[1 + ax] = math.cos(a / 2), math.sin(a / 2)
        return v

    def mul(a, b):
        w1, x1, y1, z1 = a
        w2, x2, y2, z2 = b
        return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])

    np.testing.assert_allclose(q, mul(mul(axis_quat(2, psi), axis_quat(1, theta)), axis_quat(0, phi)), atol=1e-15)


def test_with_the_autopilot_flying_the_cascade_is_off_and_command_excitation_still_reaches_the_mixer():
    v = load_vehicle("tuhh-quad")
    spec = AutopilotSpec.from_params("px4")
    runs = {}
    for exc in (None, {"u_lon": [7.0, 7.0]}):
        fs = make_flight_software(v, resolve_gains(v, None), Setup(mode="cascade", excitation=exc), 1 / 250,
                                  controller=spec)
        assert fs.attitude_by_plugin
        sig = dict(phi=0.0, theta=0.0, psi=0.0, p=0.0, q=0.0, r=0.0)
        fs.step_signals(0.0, sig)
        runs[exc is None] = sig["u_lon"]
    assert runs[True] == 0.0 and runs[False] == pytest.approx(7.0, abs=1e-12)


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_an_autopilot_alone_is_flown_on_floats_as_the_plugin_protocol_flies_it(autopilot):
    """The flight software calls the autopilot's fly() with floats when it is the only plug-in; beside another
    plug-in it goes through step() and the signal dict. Both give the same commands and rate set-points bit for
    bit over a tick sequence that saturates the commands (the integrators' saturation flags) and excites them."""
    v = load_vehicle("tuhh-quad")

    class Idle:  # a plug-in that sets nothing: forces the protocol's path
        def reset(self):
            pass

        def step(self, t, sig):
            return {}

    rng = np.random.default_rng(2)
    meas = [dict(zip(("phi", "theta", "psi", "p", "q", "r"), row)) for row in rng.normal(0.0, 20.0, (300, 6))]
    exc = rng.normal(0.0, 3.0, 300)
    runs = []
    for extra in ((), (Idle(),)):
        fs = make_flight_software(v, resolve_gains(v, None), Setup(mode="cascade", excitation={"u_lon": exc}),
                                  1 / 250, controller=AutopilotSpec.from_params(autopilot))
        fs.plugins.extend(extra)
        fs.set_reference(phi_ref=5.0, theta_ref=-3.0, psi_ref=10.0)
        out = []
        for k, m in enumerate(meas):
            sig = dict(m)
            fs.step_signals(k / 250, sig)
            out.append([sig[c] for c in ("u_lat", "u_lon", "u_yaw", "p_ref", "q_ref", "r_ref")] + list(sig["rotor_pct"]))
        runs.append(np.array(out))
    assert np.isfinite(runs[0]).all()
    assert (np.abs(runs[0][:, 0]) == fs.u_limit_pct).any()  # saturated at times: the flags were exercised
    np.testing.assert_array_equal(runs[0], runs[1], strict=True)


def test_open_loop_mode_adds_the_opened_axis_command_to_the_autopilot_and_runs_no_cascade():
    v = load_vehicle("tuhh-quad")
    spec = AutopilotSpec.from_params("px4")
    setup = Setup(mode="open-loop", open_loop_axes=("pitch",))
    fs = make_flight_software(v, resolve_gains(v, None), setup, 1 / 250, controller=spec)
    fs.set_reference(u_lon=5.0)
    meas = dict(phi=2.0, theta=1.0, psi=0.0, p=3.0, q=-2.0, r=0.0)
    sig = dict(meas)
    fs.step_signals(0.0, sig)
    alone = AutopilotController(spec, 1 / 250).step(0.0, dict(meas, phi_ref=0.0, theta_ref=0.0, psi_ref=0.0))
    assert sig["u_lat"] == pytest.approx(alone["u_lat"], rel=1e-12) and alone["u_lat"] != 0.0
    assert sig["u_lon"] == pytest.approx(alone["u_lon"] + 5.0 + sig["sup_lon"], rel=1e-12)


def test_the_twin_flies_the_parameters_loop_rate_when_it_is_a_whole_number_of_physics_steps(tmp_path):
    path = tmp_path / "fast.params"
    autopilots.write_params("px4", path, {"IMU_GYRO_RATEMAX": 1000}, "1 kHz rate loop")
    res = run_scenario("setpoint", "tuhh-quad", scene="pitch-rig", controller=parse_autopilot(f"px4:{path}"),
                       duration_s=2.0)
    c = res.info["controller"][0]
    assert res.info["control_dt_s"] == pytest.approx(0.001) and c["loop_hz"] == pytest.approx(1000.0)
    assert res.stopped is None and res.log.n == 2000  # 2 s of 1 ms ticks
    # 400 Hz is 2.5 physics steps: the vehicle's 250 Hz is flown, and run.json says both
    autopilots.write_params("px4", path, {"IMU_GYRO_RATEMAX": 400}, "400 Hz")
    res = run_scenario("setpoint", "tuhh-quad", scene="pitch-rig", controller=parse_autopilot(f"px4:{path}"),
                       duration_s=1.0)
    c = res.info["controller"][0]
    assert c["loop_hz"] == pytest.approx(250.0) and c["params_loop_hz"] == 400.0


def test_the_hover_env_flies_an_autopilot_in_place_of_the_cascade():
    from rotorlab.sim.env_hover import HoverEnv

    env = HoverEnv("tuhh-quad", control="attitude", controller=resolve_controller("ardupilot:defaults", None))
    assert env._fs.attitude_by_plugin
    env.reset(seed=0)
    hover = env.normalize_action([env.vehicle.hover_collective_pct, 2.0, 0.0, 0.0])  # 2 deg of roll asked for
    for _ in range(125):
        obs, *_ = env.step(hover)
    assert 1.5 < obs[0] < 2.5  # roll (deg) after 0.5 s at 250 Hz: ArduPilot's angle P and rate PID hold it
    env.close()


def test_cli_flies_an_autopilot_and_refuses_bad_parameter_files(tmp_path, capsys):
    from rotorlab.cli import main

    parm = tmp_path / "tuned.parm"
    autopilots.write_params("ardupilot", parm, {"ATC_RAT_PIT_P": 0.12}, "tuned: pitch rate P")
    out = tmp_path / "run"
    assert main(["run", "setpoint", "--vehicle", "tuhh-quad", "--controller", f"ardupilot:{parm}", "--duration", "3",
                 "--out", str(out), "--json"]) == 0
    assert (out / "run.json").exists()
    capsys.readouterr()
    assert main(["run", "setpoint", "--vehicle", "tuhh-quad", "--controller", f"px4:{tmp_path / 'no.params'}",
                 "--duration", "3", "--out", str(tmp_path / "r2")]) == 2
    assert "parameter file not found" in capsys.readouterr().err
    parm.write_text("ATC_RAT_PIT_P,zero\n")
    assert main(["run", "setpoint", "--vehicle", "tuhh-quad", "--controller", f"ardupilot:{parm}", "--duration", "3",
                 "--out", str(tmp_path / "r3")]) == 2
    err = capsys.readouterr().err
    assert "line 1: not a number" in err and "ATC_RAT_PIT_P" in err and "Traceback" not in err
