"""The controller seam: discrete state-space controllers flown in place of the cascade (run_scenario, the CLI),
against the cascade itself, the controller file format and its bad input."""

import json

import control as ct
import numpy as np
import pytest

from rotorlab import lti
from rotorlab.cli import main
from rotorlab.designs import design
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.gains import load_gains
from rotorlab.sim.control.statespace import ControllerSpec, StateSpaceController, load_controller, save_controller
from rotorlab.sim.env_hover import HoverEnv
from rotorlab.sim.env_rig import RigEnv
from rotorlab.sim.runner import run_scenario
from rotorlab.vehicles import gains_path

STEPS = {"steps_deg": [0.3, -0.4], "small_step_deg": 0.2, "hold_s": 1.0}


def _cascade_spec(vehicle="anteos-p2a2", dt=0.02, name="cascade-lin"):
    """The pitch cascade (outer PD on theta, inner PID on q, forward-Euler, as the flight software runs it) as
    one discrete state-space controller [theta_ref, theta, q] -> u_lon."""
    g = load_gains(gains_path(vehicle, "standard"))["pitch"]
    o, i = g.outer, g.inner
    Co = lti.as_ss(lti.pid2_ss(o.kp, o.ki, o.kd, o.tf, o.b, o.c, dt))
    Ci = lti.as_ss(lti.pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, dt))
    Co = ct.ss(Co.A, Co.B, Co.C, Co.D, dt, inputs=["r", "theta"], outputs=["q_ref"])
    Ci = ct.ss(Ci.A, Ci.B, Ci.C, Ci.D, dt, inputs=["q_ref", "q"], outputs=["u"])
    K = ct.interconnect([Co, Ci], inplist=["r", "theta", "q"], outlist=["u"], dt=dt)
    return ControllerSpec(name=name, dt_s=dt, inputs=("theta_ref", "theta", "q"), outputs=("u_lon",),
                          A=np.asarray(K.A), B=np.asarray(K.B), C=np.asarray(K.C), D=np.asarray(K.D))


def test_state_space_equal_to_the_cascade_flies_identically():
    # unsaturated, noise-free steps: the cascade's linear form flown as a plug-in gives the cascade's run
    kw = dict(scene="pitch-rig", options=STEPS, duration_s=6.0, sensor_noise=False, seed=2)
    ref = run_scenario("setpoint", "anteos-p2a2", **kw)
    ss = run_scenario("setpoint", "anteos-p2a2", controller=_cascade_spec(), **kw)
    assert np.abs(ref.log["u_lon"]).max() < 25.0  # never saturated: the linear form is the whole controller
    assert np.abs(ref.log["theta"]).max() > 0.3
    np.testing.assert_allclose(ss.log["u_lon"], ref.log["u_lon"], atol=1e-9)
    np.testing.assert_allclose(ss.log["theta"], ref.log["theta"], atol=1e-9)
    assert ss.info["controller"] == [{"name": "cascade-lin", "dt_s": 0.02, "inputs": ["theta_ref", "theta", "q"],
                                      "outputs": ["u_lon"], "states": 3, "antiwindup": False}]
    assert "controller" not in ref.info


def test_controller_runs_at_its_own_rate_and_holds_its_output():
    # a 10 Hz static gain on a 50 Hz flight software: it updates every fifth tick and holds in between
    spec = ControllerSpec(name="slow", dt_s=0.1, inputs=("theta",), outputs=("u_lon",), A=np.zeros((0, 0)),
                          B=np.zeros((0, 1)), C=np.zeros((1, 0)), D=np.array([[-0.5]]))
    r = run_scenario("gust", "anteos-p2a2", scene="pitch-rig", controller=spec, duration_s=3.0, seed=1)
    u, theta = r.log["u_lon"], r.log["theta"]
    blocks = u[: 15 * 5].reshape(15, 5)
    assert np.all(blocks == blocks[:, :1])
    np.testing.assert_array_equal(u[::5][:15], -0.5 * theta[::5][:15])
    with pytest.raises(ConfigError, match="whole multiple"):
        StateSpaceController(ControllerSpec(**{**spec.__dict__, "dt_s": 0.03}), 0.02)


def test_antiwindup_is_silent_while_unsaturated():
    kw = dict(scene="pitch-rig", duration_s=3.0, seed=4, options={"fraction": 0.1})
    plain = run_scenario("input-disturbance", "tuhh-quad", controller=design("hinf-loopshaping", "tuhh-quad"), **kw)
    aw = run_scenario("input-disturbance", "tuhh-quad", controller=design("hinf-loopshaping-aw", "tuhh-quad"), **kw)
    assert plain.info["control_dt_s"] == pytest.approx(0.004)  # the TUHH vehicle's flight-software rate
    assert np.abs(plain.log["u_lon"]).max() < 40.0
    np.testing.assert_array_equal(aw.log["u_lon"], plain.log["u_lon"])


def test_file_round_trip_json_and_toml(tmp_path):
    spec = _cascade_spec()
    p = save_controller(tmp_path / "k.json", spec)
    back = load_controller(p)
    assert back.inputs == spec.inputs and back.dt_s == spec.dt_s
    for k in "ABCD":
        np.testing.assert_array_equal(getattr(back, k), getattr(spec, k))
    rows = lambda M: "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in M) + "]"  # noqa: E731
    (tmp_path / "k.toml").write_text(
        f'name = "k"\ndt_s = 0.02\ninputs = ["theta_ref", "theta", "q"]\noutputs = ["u_lon"]\n'
        f'A = {rows(spec.A)}\nB = {rows(spec.B)}\nC = {rows(spec.C)}\nD = {rows(spec.D)}\n')
    t = load_controller(tmp_path / "k.toml")
    np.testing.assert_array_equal(t.B, spec.B)


@pytest.mark.parametrize("edit,field", [
    ({"gain": 1.0}, "gain"),
    ({"dt_s": -0.02}, "dt_s"),
    ({"B": [[1.0, 2.0]]}, "B"),
    ({"antiwindup": {"measurements": ["psi"], "A": [[0.5]], "B": [[1.0]], "C": [[1.0], [1.0]]}},
     "antiwindup.measurements"),
    ({"antiwindup": {"measurements": ["theta"], "A": [[0.5]], "B": [[1.0]], "C": [[1.0], [1.0]], "D": [[1.0]]}},
     "antiwindup.D"),
])
def test_bad_controller_file_names_file_and_field(tmp_path, edit, field):
    good = _cascade_spec().to_dict()
    p = tmp_path / "bad.json"
    p.write_text(json.dumps({**good, **edit}))
    with pytest.raises(ConfigError) as exc:
        load_controller(p)
    assert str(p) in str(exc.value) and f"field '{field}'" in str(exc.value)


def test_cli_flies_a_named_design_and_a_file(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "input-disturbance", "--vehicle", "tuhh-quad", "--controller", "hinf-loopshaping",
                 "--duration", "2", "--out", str(out)]) == 0
    info = json.loads((out / "run.json").read_text())
    assert [c["name"] for c in info["controller"]] == ["hinf-loopshaping-roll", "hinf-loopshaping-pitch"]
    f = save_controller(tmp_path / "k.json", _cascade_spec())
    assert main(["run", "setpoint", "--controller", str(f), "--duration", "1", "--out", str(tmp_path / "r2")]) == 0
    capsys.readouterr()
    assert main(["run", "setpoint", "--vehicle", "tuhh-quad", "--controller", "h2-magic", "--duration", "1",
                 "--out", str(tmp_path / "r3")]) == 2
    assert "unknown controller" in capsys.readouterr().err
    # a signal the flight software does not have is named
    bad = ControllerSpec(name="bad", dt_s=0.02, inputs=("alpha",), outputs=("u_lon",), A=np.zeros((0, 0)),
                         B=np.zeros((0, 1)), C=np.zeros((1, 0)), D=np.ones((1, 1)))
    with pytest.raises(ConfigError, match="alpha"):
        run_scenario("rest", "anteos-p2a2", scene="pitch-rig", controller=bad, duration_s=0.1)
    with pytest.raises(UnknownNameError):
        design("lqg", "tuhh-quad")


def test_gym_envs_fly_a_controller_in_place_of_the_cascade():
    ctl = design("hinf-loopshaping", "tuhh-quad", axes=("pitch",))[0]
    env = RigEnv("pitch", "tuhh-quad", control="controller", controller=ctl, task="regulation", sensor_noise=False)
    obs, _ = env.reset(seed=0, options={"setpoint_deg": 5.0})
    for _ in range(250):  # 1 s at the TUHH twin's 250 Hz: a = 0 flies the H-inf design alone
        obs, r, term, trunc, info = env.step(np.zeros(1, dtype=np.float32))
    assert not term and abs(obs[0] - 5.0) < 0.3
    with pytest.raises(ConfigError, match="controller"):
        RigEnv("pitch", "tuhh-quad", control="command", controller=ctl)
    with pytest.raises(ConfigError, match="axis command"):
        RigEnv("roll", "tuhh-quad", control="controller", controller=ctl)
    hv = HoverEnv("tuhh-quad", control="attitude", controller=design("hinf-loopshaping", "tuhh-quad"),
                  sensor_noise=False)
    hv.reset(seed=0)
    a = hv.unwrapped.normalize_action([hv.vehicle.hover_collective_pct, 0.0, 3.0, 0.0])
    for _ in range(250):
        obs, r, term, trunc, info = hv.step(a)
    assert not term and abs(obs[1] - 3.0) < 0.5  # pitch angle follows the 3 deg set-point through the H-inf loop
