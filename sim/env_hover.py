"""``rotorlab/Hover-v0``: position hold in free flight as a Gymnasium env.

**Description.** The vehicle's twin in free flight at 5 m (the free-flight scene), flown on the same
:class:`~rotorlab.sim.simulator.Simulator` as headless runs; one agent step is one flight-software tick (the vehicle's
rate: 50 Hz ANTEOS, 250 Hz TUHH). The task is to reach and hold a target position.

**Action space.** ``Box(-1, 1, (4,), float32)``, scaled affinely to physical units (``info['action_physical']``;
``env.unwrapped.normalize_action(u)`` converts back). Components outside [-1, 1] are clipped
(``info['action_clipped']``); a non-finite action raises ``ValueError`` and leaves the episode unchanged.

===  ========================================  ========  =======  ====
Num  Action, ``control='commands'`` (default)  Min       Max      Unit
===  ========================================  ========  =======  ====
0    collective command, ``50 + 50 a``         0         100      %
1    roll command                              -u_limit  u_limit  %
2    pitch command                             -u_limit  u_limit  %
3    yaw command                               -u_limit  u_limit  %
===  ========================================  ========  =======  ====

===  =================================  =========  ========  ====
Num  Action, ``control='attitude'``     Min        Max       Unit
===  =================================  =========  ========  ====
0    collective command, ``50 + 50 a``  0          100       %
1    roll set-point                     -max_tilt  max_tilt  deg
2    pitch set-point                    -max_tilt  max_tilt  deg
3    heading set-point                  -180       180       deg
===  =================================  =========  ========  ====

The commands are on the flight software's absolute scale (the mixer turns them into rotor commands); the hover
collective is not at ``a = 0`` (``normalize_action([u_hover, 0, 0, 0])`` gives it). ``u_limit`` is the vehicle's
command limit, ``max_tilt`` the ``max_tilt_deg`` argument (default 30). In ``'attitude'`` mode the vehicle's
attitude cascade (:class:`~rotorlab.sim.control.flight_software.FlightSoftware`, its ``gains``) closes the attitude
loops, or the discrete controllers given as ``controller=`` (a
:class:`~rotorlab.sim.control.statespace.ControllerSpec`, a controller file or a list; e.g.
``rotorlab.designs.design('hinf-loopshaping', 'tuhh-quad')``, or an autopilot's own laws,
``rotorlab.designs.resolve_controller('px4:defaults', None)``) on the commands they set.

**Observation space.** ``Box(float32)``, shape (18,), (24,) with ``privileged=True``; readings beyond the bounds
saturate there.

=====  ====================================================================  =====  ====  =====
Num    Observation                                                           Min    Max   Unit
=====  ====================================================================  =====  ====  =====
0-2    roll, pitch, yaw: IMU attitude estimate (noise, bias, elastic mount)  -180   180   deg
3-5    p, q, r: IMU gyro, body FRD                                           -1000  1000  deg/s
6-8    ax, ay, az: IMU accelerometer, body FRD                               -100   100   m/s^2
9-11   x, y, z: position (noise-free), NED                                   -50    50    m
12-14  vx, vy, vz: velocity (noise-free), NED                                -30    30    m/s
15-17  target x, y, z, NED                                                   -50    50    m
18-20  true airframe roll, pitch, yaw (``privileged``)                       -180   180   deg
21-23  true airframe p, q, r (``privileged``)                                -1000  1000  deg/s
=====  ====================================================================  =====  ====  =====

**Rewards.** Per step ``r = -(|position error| / 1 m)^2 - effort_weight e`` with
``e = ((u_col - u_hover) / 100)^2 + sum((u_axis / u_limit)^2)``; a crash or a flip costs 100 more.

**Starting state.** The hover keyframe at 5 m: level, at rest, every rotor at its hover trim with its lag filter and
delay line settled; sensor bias drawn from the seed; the vehicle's parameters drawn from ``randomize``, if given.
The target is drawn uniform within +-``target_range_m`` (default 1 m) of the hover point on each axis, or given
with ``reset(options={"target_m": (x, y, z)})`` (NED, within +-50 m, above ground).

**Episode end.** Terminated when the airframe tilts beyond 80 deg (a flip), hits the floor or the physics diverges
(``info['stopped']`` says which); truncated after ``episode_s`` (default 10 s: 500 steps at 50 Hz, the registered
``max_episode_steps``). ``step`` after the end raises until ``reset``.

**Arguments.** ``gymnasium.make("rotorlab/Hover-v0", **kwargs)`` with the parameters of :class:`HoverEnv` and the
common ones of :class:`~rotorlab.sim.env_base.RotorlabEnv` (``vehicle``, ``sensor_noise``, ``disturbances``,
``randomize``, ``episode_s``, ``effort_weight``, ``privileged``, ``render_mode='rgb_array'``). Reset options:
``randomize``, ``disturbances``, ``target_m``.

**Version history.** v0: the first version (normalised actions, IMU and position observations, the attitude mode
with the controller seam).
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.scenes import HOVER_HEIGHT_M
from rotorlab.sim.control.flight_software import FlightSoftware
from rotorlab.sim.env_base import RotorlabEnv, box, clip_obs
from rotorlab.sim.runner import add_controllers, resolve_gains
from rotorlab.sim.simulator import vehicle_mixer

CONTROLS = ("commands", "attitude")
_MEAS = ("phi", "theta", "psi", "p", "q", "r", "ax", "ay", "az", "x", "y", "z", "vx", "vy", "vz")
_BOUNDS = (180.0,) * 3 + (1000.0,) * 3 + (100.0,) * 3 + (50.0,) * 3 + (30.0,) * 3 + (50.0,) * 3


class HoverEnv(RotorlabEnv):
    """Free-flight position hold; see the module docstring for spaces, task and reward.

    Parameters
    ----------
    vehicle : str, path or VehicleSpec
    control : {'commands', 'attitude'}
    gains : str, path or GainSet
        Attitude cascade of ``attitude`` mode (default the vehicle's ``standard``).
    target_range_m : float
        Half-width of the random target box around the hover point, m.
    max_tilt_deg : float
        Roll/pitch set-point bound in ``attitude`` mode.
    **kwargs
        Common options of :class:`~rotorlab.sim.env_base.RotorlabEnv`.
    """

    _extra_options = ("target_m",)
    _episode_attrs = ("_k", "_target", "_fs", "_u", "_hover_col", "_meas")

    def __init__(self, vehicle="anteos-p2a2", *, control: str = "commands", gains=None, target_range_m: float = 1.0,
                 max_tilt_deg: float = 30.0, controller=None, **kwargs):
        if control not in CONTROLS:
            raise UnknownNameError("hover control", control, CONTROLS)
        if controller is not None and control != "attitude":
            raise ConfigError("a controller closes the attitude loops", field="control", expected="'attitude'",
                              got=control)
        if not target_range_m >= 0:
            raise ConfigError(field="target_range_m", expected="a half-width >= 0 m", got=target_range_m)
        if not 0 < max_tilt_deg < 80:
            raise ConfigError(field="max_tilt_deg", expected="0 < value < 80 deg", got=max_tilt_deg)
        super().__init__("free-flight", vehicle, **kwargs)
        self.control = control
        self.target_range_m = float(target_range_m)
        v = self.base_vehicle
        self.u_limit_pct = float(v.command_limit_pct)
        lim = self.u_limit_pct
        if control == "commands":
            self._set_actions([0.0, -lim, -lim, -lim], [100.0, lim, lim, lim], ["%"] * 4)
        else:
            self._set_actions([0.0, -max_tilt_deg, -max_tilt_deg, -180.0], [100.0, max_tilt_deg, max_tilt_deg, 180.0],
                              ["%", "deg", "deg", "deg"])
        hi = list(_BOUNDS) + ([180.0] * 3 + [1000.0] * 3 if self.privileged else [])
        self.observation_space = box([-x for x in hi], hi)
        self.gains = resolve_gains(v, gains)
        self._fs = FlightSoftware(self.gains, vehicle_mixer(v), dt=self.control_dt_s, mode="cascade",
                                  limits=v.commands)
        if controller is not None:
            add_controllers(self._fs, controller)
        self._target = np.array([0.0, 0.0, -HOVER_HEIGHT_M])
        self._u = np.zeros(4)

    def _start_episode(self, options: dict) -> None:
        if "target_m" in options:
            t = np.asarray(options["target_m"], dtype=float)
            if t.shape != (3,) or not np.all(np.abs(t) < 50.0) or not t[2] < 0:
                raise ConfigError(field="target_m", expected="(x, y, z) NED within +-50 m, z < 0 (above ground)",
                                  got=options["target_m"])
            self._target = t
        else:
            r = self.target_range_m
            self._target = np.array([0.0, 0.0, -HOVER_HEIGHT_M]) + self.np_random.uniform(-r, r, 3)
        self._fs.reset()
        self._hover_col = self.vehicle.hover_collective_pct  # a property computed from the spec: once per episode
        self._u = np.array([self._hover_col, 0.0, 0.0, 0.0])

    def _apply(self, action) -> float:
        sim = self.sim
        if self.control == "commands":
            self._u = sim.set_commands(action)
        else:
            fs = self._fs
            fs.set_reference(u_col=action[0], phi_ref=action[1], theta_ref=action[2], psi_ref=action[3])
            out = fs.step(sim.time, self._meas)
            sim.set_rotor_commands(out["rotor_pct"])
            self._u = np.array([out["u_col"], out["u_lat"], out["u_lon"], out["u_yaw"]])
        u = self._u
        return float(((u[0] - self._hover_col) / 100.0) ** 2
                     + np.sum((u[1:] / self.u_limit_pct) ** 2))

    def _position_error(self) -> np.ndarray:
        p = self.sim.data.xpos[self.sim._airframe]
        return np.array([p[0], -p[1], -p[2]]) - self._target

    def _reward(self, effort: float) -> float:
        e = self._position_error()
        return -float(e @ e) - self.effort_weight * effort

    def _observe(self) -> np.ndarray:
        self._meas = m = self.sim.measure()
        obs = [m[k] for k in _MEAS] + list(self._target)
        if self.privileged:
            obs += list(self.sim.true_attitude_deg()) + list(self.sim.true_rates_dps())
        return clip_obs(self.observation_space, obs)

    def _info(self) -> dict:
        return {"t": self.sim.time, "target_m": self._target.copy(), "commands_pct": np.array(self._u)}


__all__ = ["HoverEnv", "CONTROLS"]
