"""Gymnasium environments: API conformance, seeding, exact save/restore, bad input, randomisation, rendering,
and the PID baseline as a closed-loop ground truth."""

import os
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import rotorlab  # noqa: F401  (registers the envs)
from rotorlab import glbackend
from rotorlab.designs import design
from rotorlab.errors import UnknownNameError
from rotorlab.glbackend import RenderingUnavailable
from rotorlab.sim.disturbances.base import Disturbance
from rotorlab.sim.disturbances.rope_pull import RopePull
from rotorlab.sim.env_baselines import HoverPIDPolicy, RigPIDPolicy, episode_return


class TorqueKicks(Disturbance):
    """Random pitch-torque kicks on the airframe from its own seeded stream: exercises disturbance state in
    save/restore (its rng and kick level live in the disturbance object)."""

    name = "torque_kicks"
    columns = {"kick_Nm": "N m"}

    def reset(self, sim, rng):
        self.rng = rng
        self.level = 0.0

    def update(self, sim, t):
        if self.rng.random() < 0.1:
            self.level = float(self.rng.normal(0.0, 0.5))
        # world y is the rig's pitch axis (positive nose down)
        sim.data.xfrc_applied[sim._airframe, 4] = self.level

    def values(self, sim):
        return {"kick_Nm": self.level}


def _quiet(env_id, **kw):
    kw.setdefault("disable_env_checker", True)
    return gym.make(env_id, **kw).unwrapped


@pytest.mark.parametrize("env_id,kw", [
    ("rotorlab/PitchRig-v0", {}),
    ("rotorlab/RollRig-v0", {"control": "inner_loop", "privileged": True}),
    ("rotorlab/Hover-v0", {}),
    ("rotorlab/Hover-v0", {"control": "attitude", "privileged": True}),
])
def test_check_env_passes(env_id, kw):
    env = gym.make(env_id, disable_env_checker=True, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not one warning from gymnasium's checker
        check_env(env.unwrapped, skip_render_check=True)
    assert env.observation_space.dtype == np.float32 and env.action_space.dtype == np.float32
    assert np.all(env.action_space.low == -1.0) and np.all(env.action_space.high == 1.0)
    assert env.spec.max_episode_steps == 500


def test_actions_are_normalised_and_scaled_to_physical_units():
    """a in [-1, 1] maps affinely onto the documented physical range; info reports the applied command."""
    env = _quiet("rotorlab/PitchRig-v0")
    env.reset(seed=0)
    lim = env.base_vehicle.command_limit_pct
    assert env.action_units == ("%",) and env.action_high[0] == lim == 30.0
    obs, _, _, _, info = env.step([0.5])
    assert info["action_physical"] == [0.5 * lim] and obs[3] == pytest.approx(0.5 * lim)
    assert env.normalize_action([0.5 * lim])[0] == pytest.approx(0.5)
    hover = _quiet("rotorlab/Hover-v0", control="attitude")
    hover.reset(seed=0)
    _, _, _, _, info = hover.step([-1.0, 0.0, 1.0, 0.5])
    assert info["action_physical"] == [0.0, 0.0, 30.0, 90.0]  # collective [0, 100] %, tilt +-30 deg, heading +-180 deg
    assert hover.action_units == ("%", "deg", "deg", "deg")
    np.testing.assert_allclose(hover.physical_action(hover.normalize_action([55.0, 3.0, -4.0, 10.0])),
                               [55.0, 3.0, -4.0, 10.0], rtol=1e-6)


def test_make_vec_sync():
    venv = gym.make_vec("rotorlab/PitchRig-v0", num_envs=2, vectorization_mode="sync")
    obs, _ = venv.reset(seed=5)
    assert obs.shape == (2, 4)
    obs2, rew, term, trunc, _ = venv.step(np.array([[0.1], [-0.1]], dtype=np.float32))
    assert obs2.shape == (2, 4) and rew.shape == (2,) and not term.any()
    # the two sub-envs draw different set-points and noise
    assert obs[0, 2] != obs[1, 2]
    venv.close()


def _rollout(env, actions):
    return np.array([env.step(a)[0] for a in actions])


def _snapshot_replays(env, actions):
    """Snapshot ``env``, roll ``actions`` out, restore and roll them again: the two continuations are equal to
    the bit. Returns the snapshot and the continuation."""
    snap = env.save_state()
    first = _rollout(env, actions)
    env.restore_state(snap)
    np.testing.assert_array_equal(_rollout(env, actions), first)
    return snap, first


def test_seeding_is_reproducible():
    env = _quiet("rotorlab/PitchRig-v0")
    acts = np.random.default_rng(0).uniform(-0.3, 0.3, (30, 1))
    o1 = env.reset(seed=11)[0]
    r1 = _rollout(env, acts)
    o2 = env.reset(seed=11)[0]
    r2 = _rollout(env, acts)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(r1, r2)
    env.reset(seed=12)
    assert not np.array_equal(_rollout(env, acts), r1)


@pytest.mark.parametrize("env_id,kw", [
    ("rotorlab/PitchRig-v0", {"control": "inner_loop", "disturbances": [TorqueKicks()]}),
    ("rotorlab/Hover-v0", {"control": "attitude"}),
])
def test_save_restore_is_exact(env_id, kw):
    env = _quiet(env_id, **kw)
    env.reset(seed=3)
    rng = np.random.default_rng(1)
    lo, hi = env.action_space.low, env.action_space.high
    mid = (lo + hi) / 2
    acts = mid + 0.2 * (hi - lo) * rng.uniform(-0.5, 0.5, (60,) + lo.shape)
    _rollout(env, acts[:20])
    snap, first = _snapshot_replays(env, acts[20:])
    # the snapshot is not consumed: restoring twice gives the same continuation again
    env.restore_state(snap)
    np.testing.assert_array_equal(_rollout(env, acts[20:]), first)


@pytest.mark.parametrize("env_id,kw,options", [
    ("rotorlab/PitchRig-v0", {"control": "controller", "axes": ("pitch",)}, {"setpoint_deg": 25.0}),
    ("rotorlab/Hover-v0", {"control": "attitude", "axes": ("roll", "pitch")}, {}),
])
def test_save_restore_is_exact_with_a_flown_controller(env_id, kw, options):
    # the flown controller's states (its own and, on the rig, its anti-windup compensator's after the 25 deg
    # step saturated the command) are part of the snapshot
    ctl = design("hinf-loopshaping-aw", "tuhh-quad", axes=kw.pop("axes"))
    env = _quiet(env_id, vehicle="tuhh-quad", controller=ctl[0] if len(ctl) == 1 else ctl, **kw)
    env.reset(seed=4, options=options)
    lo, hi = env.action_space.low, env.action_space.high
    acts = 0.1 * np.where(np.arange(80)[:, None] % 10 < 5, hi, lo) * np.ones_like(lo)
    _rollout(env, acts[:23])
    plugins = [env._ctl] if options else env._fs.plugins
    assert all(np.any(pl.x != 0) for pl in plugins) and (not options or np.any(plugins[0].x_aw != 0))
    _snapshot_replays(env, acts[23:])


def test_save_restore_is_exact_through_a_rope_pull():
    env = _quiet("rotorlab/PitchRig-v0", task="regulation", disturbances=[RopePull(t_pull_s=0.6, ramp_s=0.3)])
    env.reset(seed=0)
    acts = np.full((90, 1), 2.0 / 30.0)  # 2 % of command
    _rollout(env, acts[:20])
    _, first = _snapshot_replays(env, acts[20:])
    assert np.min(first[:, 0]) < -5.0  # the rope really pulled the nose down in between


def test_out_of_range_action_is_clipped_to_bounds():
    a, b = _quiet("rotorlab/PitchRig-v0"), _quiet("rotorlab/PitchRig-v0")
    a.reset(seed=2)
    b.reset(seed=2)
    oa, _, _, _, ia = a.step([1e6])
    ob, _, _, _, ib = b.step([1.0])
    np.testing.assert_array_equal(oa, ob)
    assert ia["action_clipped"] and not ib["action_clipped"]
    # the observation reports the applied (clipped) action, in % of command
    assert oa[3] == pytest.approx(a.base_vehicle.command_limit_pct)


def test_nan_action_raises_and_leaves_the_episode_intact():
    a, b = _quiet("rotorlab/PitchRig-v0"), _quiet("rotorlab/PitchRig-v0")
    a.reset(seed=4)
    b.reset(seed=4)
    acts = np.full((10, 1), 4.0 / 30.0)
    _rollout(a, acts[:5])
    _rollout(b, acts[:5])
    with pytest.raises(ValueError, match="not finite"):
        a.step([np.nan])
    with pytest.raises(ValueError, match="components"):
        a.step([1.0, 2.0])
    np.testing.assert_array_equal(_rollout(a, acts[5:]), _rollout(b, acts[5:]))


def test_unknown_reset_option_lists_valid_keys():
    env = _quiet("rotorlab/PitchRig-v0")
    with pytest.raises(UnknownNameError, match="setpoint_deg") as ei:
        env.reset(seed=0, options={"set_point": 3.0})
    assert "randomize" in str(ei.value) and "set_point" in str(ei.value)
    with pytest.raises(UnknownNameError, match="mass"):
        env.reset(seed=0, options={"randomize": {"weight": 0.1}})


def test_domain_randomisation_rebuilds_the_model_with_sampled_parameters():
    env = _quiet("rotorlab/PitchRig-v0", randomize={"mass": 0.2, "inertia": 0.2, "delay_s": (0.04, 0.08)})
    base = env.base_vehicle
    masses, delays = set(), set()
    for s in range(4):
        env.reset(seed=s)
        v, m = env.vehicle, env.sim.model
        assert 0.8 * base.mass_kg <= v.mass_kg <= 1.2 * base.mass_kg
        # the compiled model carries the sampled vehicle mass (airframe, IMU board, rotor discs) and delay line
        air = m.body("vehicle/airframe").id
        assert m.body_subtreemass[air] == pytest.approx(v.mass_kg)
        act = m.actuator("vehicle/thrust1").id
        # the history buffer holds delay/dt + 1 samples (rotorlab.vehicles.build)
        assert m.actuator_history[act, 0] == round(v.rotor.delay_s[0] / m.opt.timestep) + 1
        assert 0.04 - 1e-12 <= v.rotor.delay_s[0] <= 0.08 + 1e-12
        masses.add(v.mass_kg)
        delays.add(v.rotor.delay_s[0])
    assert len(masses) == 4 and len(delays) >= 2
    # same seed -> same draw, served from the cache
    env.reset(seed=1)
    sim1 = env.sim
    env.reset(seed=1)
    assert env.sim is sim1
    # options override the make-time spreads; {} turns randomisation off
    env.reset(seed=0, options={"randomize": {}})
    assert env.vehicle.mass_kg == base.mass_kg


def test_reward_is_the_documented_tracking_error():
    env = _quiet("rotorlab/PitchRig-v0", sensor_noise=False, effort_weight=0.0)
    env.reset(seed=0, options={"setpoint_deg": 5.0})
    _, r, *_ = env.step([0.0])
    # at rest on the rig (true angle ~0) the error is the whole 5 deg: -(5/10)^2
    assert r == pytest.approx(-0.25, abs=2e-3)


def test_pid_baseline_tracks_the_setpoint_on_the_rig():
    env = _quiet("rotorlab/PitchRig-v0", sensor_noise=False, episode_s=4.0)
    pol = RigPIDPolicy(env)
    obs, _ = env.reset(seed=0, options={"setpoint_deg": 5.0})
    pol.reset()
    for _ in range(200):
        obs, r, term, trunc, _ = env.step(pol(obs))
    # integral action: no steady-state error after 4 s with the published standard gains
    assert obs[0] == pytest.approx(5.0, abs=0.1)
    assert r > -1e-3


def test_inner_loop_mode_closes_the_rate_loop():
    env = _quiet("rotorlab/PitchRig-v0", control="inner_loop", sensor_noise=False, privileged=True)
    env.reset(seed=0, options={"task": "regulation"})
    rates = []
    for _ in range(150):  # 3 s at 5 deg/s: about 11 deg, inside the +-30 deg stops
        obs, *_ = env.step(env.normalize_action([5.0]))
        rates.append(obs[5])
    err = 5.0 - np.array(rates)
    # the integral drives the true rate to the set-point (published inner gains: kp/ki = 0.4 s, slow tail)
    assert np.all(np.diff(err[10:]) < 0)
    assert 0.0 < err[-1] < 0.5


def test_pid_baseline_holds_position_in_flight():
    env = _quiet("rotorlab/Hover-v0", episode_s=6.0)
    ret, steps, terminated = episode_return(env, HoverPIDPolicy(env), seed=0)
    assert not terminated and steps == 300
    obs = env._observe()
    assert np.linalg.norm(obs[9:12] - obs[15:18]) < 0.2


def test_disturbance_from_reset_options():
    env = _quiet("rotorlab/PitchRig-v0", sensor_noise=False)
    env.reset(seed=0, options={"task": "regulation"})
    quiet = _rollout(env, np.zeros((50, 1)))
    env.reset(seed=0, options={"task": "regulation", "disturbances": [TorqueKicks()]})
    kicked = _rollout(env, np.zeros((50, 1)))
    assert np.max(np.abs(kicked[:, 0])) > np.max(np.abs(quiet[:, 0])) + 1.0


def test_render_rgb_array_headless():
    """With a backend (a display, or EGL / OSMesa, which `import rotorlab` picks headless) the env renders the
    scene; without one, asking for 'rgb_array' says what to install (the test is then skipped)."""
    try:
        env = _quiet("rotorlab/PitchRig-v0", render_mode="rgb_array")
    except RenderingUnavailable as exc:
        assert glbackend.render_modes() == [] and "libegl" in str(exc).lower()
        pytest.skip(f"no OpenGL backend on this machine: {exc}")
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert img.std() > 5.0  # a scene, not a blank frame
    env.close()


#: gymnasium's check_env on every registered env, render modes included, then 'rgb_array' asked for, in a fresh
#: interpreter whose environment has no MUJOCO_GL (as a user's shell); prints the backend and the render outcome
_CHECK_ALL = """
import warnings
import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import rotorlab
from rotorlab import glbackend
ids = [i for i in gym.registry if i.startswith("rotorlab/")]
assert len(ids) == 3, ids
for i in ids:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(i, disable_env_checker=True).unwrapped)
try:
    env = gym.make(ids[0], render_mode="rgb_array", disable_env_checker=True).unwrapped
    env.reset(seed=0)
    print("rendered", env.render().shape)
except glbackend.RenderingUnavailable as exc:
    print("unavailable:", exc)
import os
print("MUJOCO_GL", os.environ.get("MUJOCO_GL"), "modes", glbackend.render_modes())
"""
#: the same where no EGL or OSMesa library loads (hidden from ctypes before rotorlab picks a backend)
_NO_GL_LIBS = """
import ctypes
class _Hidden(ctypes.CDLL):
    def __init__(self, name, *a, **k):
        if name and ("EGL" in name or "OSMesa" in name):
            raise OSError(f"{name}: hidden by the test")
        super().__init__(name, *a, **k)
ctypes.CDLL = _Hidden
"""


def _run_clean(code):
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY",
                                                               "WAYLAND_DISPLAY")}
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    return p.stdout


LINUX_ONLY = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="macOS and Windows render without MUJOCO_GL; the choice is Linux's")


@LINUX_ONLY
def test_check_env_passes_on_every_env_without_mujoco_gl():
    """README: check_env passes without a warning, with MUJOCO_GL unset and no display. rotorlab picks EGL (or
    OSMesa) itself and the envs render; where neither library loads they declare no render mode, check_env still
    passes, and 'rgb_array' raises RenderingUnavailable naming what to install."""
    out = _run_clean(_CHECK_ALL)
    assert ("rendered (480, 640, 3)" in out) == (glbackend.choose() is not None), out
    out = _run_clean(_NO_GL_LIBS + _CHECK_ALL)
    assert "MUJOCO_GL None modes []" in out and "unavailable: no OpenGL backend" in out, out
    assert "libegl1" in out and "libosmesa6" in out, out


@LINUX_ONLY
def test_backend_choice_leaves_a_user_setting_alone(monkeypatch):
    for k in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.delitem(sys.modules, "mujoco")  # as before MuJoCo's first import
    monkeypatch.setattr(glbackend, "BACKENDS", (("egl", ("libEGL-that-is-not-there.so",)),))
    assert glbackend.select() is None and "MUJOCO_GL" not in os.environ and glbackend.render_modes() == []
    monkeypatch.setattr(glbackend, "BACKENDS", (("osmesa", ("libc.so.6",)),))  # a library that loads
    assert glbackend.select() == "osmesa" and os.environ["MUJOCO_GL"] == "osmesa"
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    assert glbackend.select() is None and os.environ["MUJOCO_GL"] == "glfw"
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.delenv("MUJOCO_GL")
    assert glbackend.select() is None and glbackend.render_modes() == ["rgb_array"]
