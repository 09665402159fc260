"""What the Gymnasium environments share: the simulator per (randomised) vehicle, seeding, domain
randomisation, exact full-state save/restore, bad-action handling and headless rendering.

The environments run the same :class:`~rotorlab.sim.simulator.Simulator` as headless runs: one agent step is
one flight-software tick (50 Hz), i.e. ``Simulator.tick()`` batching the physics steps (1 kHz) in one
``mj_step(m, d, nstep)`` call with the command held (zero-order hold). The tick ends with the derived quantities
(sensors) recomputed for the new state, so the observation is a function of the physics state alone: this is what
makes :meth:`RotorlabEnv.restore_state` exact.

Domain randomisation (``randomize=`` at ``make`` or in ``reset(options=...)``)
-------------------------------------------------------------------------------
A dict of parameter -> spread (``mass``, ``inertia``, ``motor_lag``, ``imu_mount``, ``delay_s``), drawn at every
reset from the env's seeded generator with the distributions of :mod:`rotorlab.sim.randomize` (the same as
``rotorlab montecarlo`` and the batched runner). The vehicle is rebuilt with ``dataclasses.replace`` and the scene
recompiled; compiled simulators are cached per parameter set (LRU, :data:`SIM_CACHE_SIZE`), so a randomised reset
costs one scene compile (tens of ms).
"""

from __future__ import annotations

import collections
import collections.abc
import copy
import dataclasses
import math
import numbers

import gymnasium as gym
import mujoco
import numpy as np

from rotorlab import glbackend
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.sim import randomize
from rotorlab.sim.simulator import Simulator
from rotorlab.vehicles import VehicleSpec, load_vehicle

SIM_CACHE_SIZE = 16
#: the randomisation parameters of the envs (wind is a disturbance there: ``disturbances=``)
RANDOMIZE_KEYS = ("mass", "inertia", "motor_lag", "imu_mount", "delay_s")
RENDER_SIZE = (480, 640)  # height, width: the scenes' offscreen buffer


@dataclasses.dataclass
class EnvState:
    """A snapshot from :meth:`RotorlabEnv.save_state`: MuJoCo's full physics state (``mjSTATE_FULLPHYSICS``:
    time, qpos, qvel, act, actuator history/delay buffers, warm start, applied forces, mocap), the warning
    counters, and a deep copy of the flight-software, disturbance and env episode state."""

    sim: Simulator
    physics: np.ndarray
    warnings: np.ndarray
    python: dict


def randomized_vehicle(v: VehicleSpec, spreads: dict, rng: np.random.Generator, physics_dt_s: float):
    """Draw one vehicle from ``spreads`` (:mod:`rotorlab.sim.randomize`); returns ``(vehicle, key)`` where ``key``
    is the hashable parameter set the compiled scene is cached under."""
    if not isinstance(spreads, collections.abc.Mapping):
        raise ConfigError(field="randomize", expected="a dict {parameter: spread}", got=spreads)
    out = randomize.apply(v, randomize.draw(v, spreads, rng, physics_dt_s, keys=RANDOMIZE_KEYS))
    key = (round(out.mass_kg, 12), tuple(round(j, 12) for j in out.inertia_kgm2),
           tuple(round(t, 12) for t in out.rotor.lag_s), tuple(round(d, 9) for d in out.rotor.delay_s),
           round(out.imu.mount_frequency_hz, 12))
    return out, key


def _disturbances(dists, field: str) -> list:
    """A list of disturbance objects (duck-typed on the Disturbance interface the simulator calls)."""
    if isinstance(dists, (str, bytes, collections.abc.Mapping)) or not isinstance(dists, collections.abc.Iterable):
        raise ConfigError(field=field, expected="a sequence of Disturbance objects", got=dists)
    out = list(dists)
    for i, d in enumerate(out):
        if not all(callable(getattr(d, m, None)) for m in ("reset", "update", "values", "edit", "check_scene")):
            raise ConfigError(field=f"{field}[{i}]", expected="a rotorlab.sim.disturbances Disturbance",
                              got=type(d).__name__)
    return out


class RotorlabEnv(gym.Env):
    """Base class: subclasses define the spaces, ``_apply(action)``, ``_observe()``, ``_reward()`` and the
    episode set-up ``_start_episode(options)``. The parameters below are common to every rotorlab env.

    Parameters
    ----------
    scene : str
        Scene name (``pitch-rig``, ``roll-rig``, ``free-flight``).
    vehicle : str, path or VehicleSpec
        Vehicle name or TOML path.
    sensor_noise : bool
        Seeded IMU noise and bias.
    disturbances : sequence
        Objects following :class:`rotorlab.sim.disturbances.base.Disturbance` (wind, gust, rope ...).
    randomize : dict, optional
        Domain randomisation spreads (module docstring).
    episode_s : float
        Episode length, s (truncation).
    effort_weight : float
        Weight of the control-effort penalty in the reward.
    privileged : bool
        Append the true (noise-free, airframe rather than IMU) state to the observation.
    render_mode : {None, 'rgb_array'}
        'rgb_array' needs an OpenGL backend (:mod:`rotorlab.glbackend`: a display, EGL or OSMesa); without one
        it raises :class:`rotorlab.glbackend.RenderingUnavailable`.
    """

    #: 'rgb_array' where MuJoCo has an OpenGL backend (rotorlab.glbackend), else none: gymnasium's check_env
    #: then checks the env without rendering, and asking for 'rgb_array' says what to install
    metadata = {"render_modes": glbackend.render_modes(), "render_fps": 50}
    #: reset option keys every env accepts; subclasses extend with :attr:`_extra_options`
    _base_options = ("randomize", "disturbances")
    _extra_options: tuple = ()

    def __init__(self, scene: str, vehicle, *, sensor_noise: bool = True, disturbances=(), randomize=None,
                 episode_s: float = 10.0, effort_weight: float = 0.01, privileged: bool = False,
                 render_mode: str | None = None):
        if render_mode is not None and render_mode != "rgb_array":
            raise UnknownNameError("render mode", str(render_mode), ["rgb_array"])
        if render_mode is not None:
            glbackend.require()
        for name, val in (("episode_s", episode_s), ("effort_weight", effort_weight)):
            if isinstance(val, bool) or not isinstance(val, numbers.Real) or not math.isfinite(val):
                raise ConfigError(field=name, expected="a finite number", got=val)
        if not episode_s > 0:
            raise ConfigError(field="episode_s", expected="an episode length > 0 s", got=episode_s)
        if not effort_weight >= 0:
            raise ConfigError(field="effort_weight", expected="a weight >= 0", got=effort_weight)
        self.render_mode = render_mode
        self.scene_name = scene
        self.base_vehicle = vehicle if isinstance(vehicle, VehicleSpec) else load_vehicle(vehicle)
        self.sensor_noise = bool(sensor_noise)
        self.episode_s = float(episode_s)
        self.effort_weight = float(effort_weight)
        self.privileged = bool(privileged)
        if randomize is not None and not isinstance(randomize, collections.abc.Mapping):
            raise ConfigError(field="randomize", expected="a dict {parameter: spread}", got=randomize)
        self._default_randomize = dict(randomize or {})
        self._default_disturbances = _disturbances(disturbances, "disturbances")
        self._cache: collections.OrderedDict = collections.OrderedDict()
        self._renderers: dict = {}
        self.sim = self._simulator(self.base_vehicle, None, self._default_disturbances)
        self.vehicle = self.sim.vehicle
        self.control_dt_s = self.sim.control_dt_s
        self.n_steps = int(round(self.episode_s / self.control_dt_s))
        self._k = 0
        self._ended = None

    # ------------------------------------------------------------------ simulators
    def _simulator(self, vehicle, key, disturbances) -> Simulator:
        key = (key, tuple(id(d) for d in disturbances))
        sim = self._cache.get(key)
        if sim is None:
            sim = Simulator(self.scene_name, vehicle, sensor_noise=self.sensor_noise, disturbances=disturbances)
            self._cache[key] = sim
            while len(self._cache) > SIM_CACHE_SIZE:
                old = self._cache.popitem(last=False)[1]
                r = self._renderers.pop(id(old.model), None)
                if r is not None:
                    r.close()
        else:
            self._cache.move_to_end(key)
        return sim

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode. ``options`` keys: ``randomize``, ``disturbances`` and the env's own
        (:attr:`valid_options`); an unknown key raises ``UnknownNameError`` listing the valid ones."""
        super().reset(seed=seed)
        if options is not None and not isinstance(options, collections.abc.Mapping):
            raise ConfigError(field="options", expected="a dict of reset options", got=options)
        options = dict(options or {})
        for k in options:
            if k not in self.valid_options:
                raise UnknownNameError("reset option", k, self.valid_options)
        spreads = options.get("randomize", self._default_randomize)
        dists = _disturbances(options.get("disturbances", self._default_disturbances), "options.disturbances")
        physics_dt = float(self.sim.model.opt.timestep)
        if spreads:
            v, key = randomized_vehicle(self.base_vehicle, spreads, self.np_random, physics_dt)
        else:
            v, key = self.base_vehicle, None
        self.sim = self._simulator(v, key, dists)
        self.vehicle = self.sim.vehicle
        self.sim.reset(int(self.np_random.integers(2**31)))
        self._k = 0
        self._ended = None
        self._start_episode(options)
        return self._observe(), self._info()

    def _set_actions(self, low, high, units) -> None:
        """Physical range and units of the action components; the action space becomes ``Box(-1, 1)``."""
        self.action_low = np.asarray(low, dtype=float)
        self.action_high = np.asarray(high, dtype=float)
        self.action_units = tuple(units)
        n = self.action_low.size
        self.action_space = box([-1.0] * n, [1.0] * n)
        # plain lists: the per-step mapping is a few scalar operations (numpy calls cost more at n <= 4)
        self._a_mid = ((self.action_low + self.action_high) / 2).tolist()
        self._a_half = ((self.action_high - self.action_low) / 2).tolist()

    def physical_action(self, action) -> np.ndarray:
        """A normalised action (clipped to [-1, 1]) in physical units (:attr:`action_units`)."""
        a = np.clip(np.asarray(action, dtype=float).ravel(), -1.0, 1.0)
        return np.asarray(self._a_mid) + np.asarray(self._a_half) * a

    def normalize_action(self, physical) -> np.ndarray:
        """A physical action (:attr:`action_units`) as the normalised float32 action the env takes."""
        p = np.asarray(physical, dtype=float).ravel()
        return ((p - np.asarray(self._a_mid)) / np.asarray(self._a_half)).astype(np.float32)

    @property
    def valid_options(self) -> tuple:
        return self._base_options + self._extra_options

    def step(self, action):
        if self._ended is not None:
            # MuJoCo would keep integrating past the rig stop or the crash: an ended episode needs reset()
            raise RuntimeError(f"the episode has ended ({self._ended}); call reset() before step()")
        # plain-Python checks: for 1-4 components they are several times cheaper than numpy calls, per step
        a = np.asarray(action, dtype=float).ravel().tolist()
        mid, half = self._a_mid, self._a_half
        if len(a) != len(mid):
            raise ValueError(f"action has {len(a)} components; the action space has shape {self.action_space.shape}")
        if not all(map(math.isfinite, a)):
            raise ValueError(f"action {a} is not finite; the episode state is unchanged")
        # documented rule: out-of-range components are clipped to [-1, 1], then scaled to physical units
        clipped = [-1.0 if x < -1.0 else (1.0 if x > 1.0 else x) for x in a]
        was_clipped = clipped != a
        phys = [m + h * x for x, m, h in zip(clipped, mid, half)]
        effort = self._apply(phys)
        sim = self.sim
        sim.tick()
        self._k += 1
        reason = sim.check()
        terminated = reason is not None
        reward = self._reward(effort) - (self.termination_penalty if terminated else 0.0)
        truncated = (not terminated) and self._k >= self.n_steps
        info = self._info()
        info["action_clipped"] = was_clipped
        info["action_physical"] = phys
        if terminated:
            info["stopped"] = reason
            self._ended = f"terminated: {reason}"
        elif truncated:
            self._ended = f"truncated after {self.n_steps} steps"
        return self._observe(), float(reward), terminated, truncated, info

    termination_penalty = 100.0

    def _info(self) -> dict:
        return {"t": self.sim.time}

    # ------------------------------------------------------------------ state
    def _memo(self) -> dict:
        # objects the deep copies must share, not duplicate (MuJoCo model/data, the vehicle spec)
        s = self.sim
        return {id(o): o for o in (s, s.model, s.data, s.scene, s.vehicle, s.mixer, self, self.base_vehicle)}

    _episode_attrs: tuple = ("_k",)

    def save_state(self) -> EnvState:
        """Snapshot everything a later :meth:`restore_state` needs to continue bit-for-bit."""
        s = self.sim
        m, d = s.model, s.data
        sig = mujoco.mjtState.mjSTATE_FULLPHYSICS
        phys = np.empty(mujoco.mj_stateSize(m, sig))
        mujoco.mj_getState(m, d, phys, sig)
        py = {"sim": {k: getattr(s, k) for k in s.python_state_attrs},
              "dist": [dict(dd.__dict__) for dd in s.disturbances],
              "env": {k: getattr(self, k) for k in self._episode_attrs},
              "np_random": self.np_random}
        return EnvState(s, phys, np.array([w.number for w in d.warning]), copy.deepcopy(py, self._memo()))

    def restore_state(self, state: EnvState) -> None:
        """Return to a :meth:`save_state` snapshot (same episode parameters, same simulator)."""
        if not isinstance(state, EnvState):
            raise ConfigError(field="state", expected="an EnvState from save_state()", got=type(state).__name__)
        self.sim = s = state.sim
        self.vehicle = s.vehicle
        self._ended = None
        m, d = s.model, s.data
        mujoco.mj_setState(m, d, state.physics, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for w, n in zip(d.warning, state.warnings):
            w.number = int(n)
        py = copy.deepcopy(state.python, self._memo())
        for k, v in py["sim"].items():
            setattr(s, k, v)
        for dd, saved in zip(s.disturbances, py["dist"]):
            dd.__dict__.update(saved)
        for k, v in py["env"].items():
            setattr(self, k, v)
        self._np_random = py["np_random"]
        mujoco.mj_forward(m, d)

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode != "rgb_array":
            return None
        s = self.sim
        r = self._renderers.get(id(s.model))
        if r is None:
            r = self._renderers[id(s.model)] = glbackend.renderer(s.model, *RENDER_SIZE)
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        body = s._airframe
        cam.lookat[:] = s.data.xpos[body] if body >= 0 else [0.0, 0.0, 1.0]
        cam.distance = 4.0 * max(self.vehicle.arm_m, 0.3)
        cam.azimuth, cam.elevation = 120.0, -20.0
        r.update_scene(s.data, cam)
        return r.render()

    def close(self):
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()
        super().close()


def box(low, high) -> gym.spaces.Box:
    return gym.spaces.Box(np.asarray(low, dtype=np.float32), np.asarray(high, dtype=np.float32), dtype=np.float32)


def clip_obs(space: gym.spaces.Box, values) -> np.ndarray:
    """Observation as float32 inside ``space`` (sensor values beyond the documented range saturate, as a real
    sensor's range does)."""
    # two ufuncs: np.clip's Python-level wrapper costs more than the clipping itself, every step
    return np.minimum(np.maximum(np.asarray(values, dtype=np.float32), space.low), space.high)


def wrap180(angle_deg: float) -> float:
    return (angle_deg + 180.0) % 360.0 - 180.0


__all__ = ["RotorlabEnv", "EnvState", "randomized_vehicle", "RANDOMIZE_KEYS", "box", "clip_obs", "wrap180"]
