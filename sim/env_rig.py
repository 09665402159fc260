"""``rotorlab/PitchRig-v0`` and ``rotorlab/RollRig-v0``: the 1-DoF gimbal test-bed as a Gymnasium env.

**Description.** The vehicle's twin clamped to the published 1-DoF test-bed (pitch or roll rig: a light ring on a
greased bearing), flown on the same :class:`~rotorlab.sim.simulator.Simulator` as headless runs. One agent step is
one flight-software tick (the vehicle's rate: 50 Hz ANTEOS, 250 Hz TUHH; physics at 1 kHz). The task is to track
angle set-point steps (``task='tracking'``) or to hold the rig level against disturbances (``task='regulation'``).

**Action space.** ``Box(-1, 1, (1,), float32)``, scaled affinely to physical units (``info['action_physical']``;
``env.unwrapped.normalize_action(u)`` converts back). Components outside [-1, 1] are clipped
(``info['action_clipped']``); a non-finite action raises ``ValueError`` and leaves the episode unchanged.

===  =======================================================  ===========  ===========  =====
Num  Action (by ``control``)                                  Min          Max          Unit
===  =======================================================  ===========  ===========  =====
0    ``'command'``: the axis command                          -u_limit     +u_limit     %
0    ``'inner_loop'``: the rate set-point (inner PID closed)  -rate_limit  +rate_limit  deg/s
0    ``'controller'``: a residual on the controller's output  -u_limit     +u_limit     %
===  =======================================================  ===========  ===========  =====

``u_limit`` is the vehicle's command limit (30 % P2-A2, 40 % A2-MINI/B, ``[commands] limit_pct``), ``rate_limit``
its rate limit (``[commands] rate_limit_dps``, or ``rate_limit_dps=``). In ``'inner_loop'`` mode the vehicle's inner
PID (its ``gains``, :class:`~rotorlab.sim.control.pid.DiscretePID` with clamping anti-windup) closes the rate loop;
in ``'controller'`` mode a discrete controller (``controller=``, a
:class:`~rotorlab.sim.control.statespace.ControllerSpec` or file setting the axis command) is flown and the action
adds to its output before the saturation (``a = 0`` flies the controller alone).

**Observation space.** ``Box(float32)``, shape (4,), (6,) with ``privileged=True``; readings beyond the bounds
saturate there.

===  =============================================================  ======  ======  ==========
Num  Observation                                                    Min     Max     Unit
===  =============================================================  ======  ======  ==========
0    rig angle, IMU attitude estimate (noise, bias, elastic mount)  -90     90      deg
1    rig-axis rate, IMU gyro                                        -1000   1000    deg/s
2    angle set-point                                                -90     90      deg
3    last applied (clipped) action, physical                        -bound  +bound  % or deg/s
4    true airframe angle (``privileged``)                           -90     90      deg
5    true airframe rate (``privileged``)                            -1000   1000    deg/s
===  =============================================================  ======  ======  ==========

**Rewards.** Per step ``r = -((angle_true - set-point) / 10 deg)^2 - effort_weight (u / u_limit)^2``, with ``u`` the
axis command actually sent; reaching the rig stop costs 100 more.

**Starting state.** The hover keyframe: the rig level (0 deg) at rest, every rotor at its trim with its lag filter
and delay line settled; sensor bias drawn from the seed; the vehicle's parameters drawn from ``randomize``, if
given. Tracking: the set-point sequence (a new value uniform in +-``setpoint_max_deg`` every ``setpoint_period_s``)
is drawn at reset; ``reset(options={"setpoint_deg": x})`` holds ``x`` instead.

**Episode end.** Terminated when the rig reaches its stop (the vehicle's ``[rig] stop_deg``, 30 deg on the ANTEOS
twins) or the physics diverges (``info['stopped']`` says which); truncated after ``episode_s`` (default 10 s: 500
steps at 50 Hz, the registered ``max_episode_steps``). ``step`` after the end raises until ``reset``.

**Arguments.** ``gymnasium.make("rotorlab/PitchRig-v0", **kwargs)`` (``RollRig-v0``: ``axis='roll'``) with the
parameters of :class:`RigEnv` and the common ones of :class:`~rotorlab.sim.env_base.RotorlabEnv`
(``vehicle``, ``sensor_noise``, ``disturbances``, ``randomize``, ``episode_s``, ``effort_weight``, ``privileged``,
``render_mode='rgb_array'``). Reset options: ``randomize``, ``disturbances``, ``task``, ``setpoint_deg``.

**Version history.** v0: the first version (normalised actions, the IMU observation through the elastic mount,
the published test-bed, the controller seam).
"""

from __future__ import annotations

import math

import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.sim.control.pid import DiscretePID
from rotorlab.sim.control.statespace import StateSpaceController, as_controller_spec
from rotorlab.sim.env_base import RotorlabEnv, box, clip_obs
from rotorlab.sim.runner import resolve_gains

CONTROLS = ("command", "inner_loop", "controller")
TASKS = ("tracking", "regulation")
ANGLE_BOUND_DEG = 90.0
RATE_BOUND_DPS = 1000.0
ERROR_SCALE_DEG = 10.0
_AXIS = {"pitch": ("pitch-rig", 2, "theta", "q", 1), "roll": ("roll-rig", 1, "phi", "p", 0)}


class RigEnv(RotorlabEnv):
    """The pitch or roll test-bed; see the module docstring for spaces, task and reward.

    Parameters
    ----------
    axis : {'pitch', 'roll'}
    vehicle : str, path or VehicleSpec
    control : {'command', 'inner_loop'}
    gains : str, path or GainSet
        Gain set whose inner loop closes the rate loop in ``inner_loop`` mode (default the vehicle's ``standard``).
    task : {'tracking', 'regulation'}
    setpoint_max_deg, setpoint_period_s : float
        Set-point steps of the tracking task.
    rate_limit_dps : float, optional
        Rate set-point bound in ``inner_loop`` mode (default the vehicle's ``commands.rate_limit_dps``).
    **kwargs
        Common options of :class:`~rotorlab.sim.env_base.RotorlabEnv` (``sensor_noise``, ``disturbances``,
        ``randomize``, ``episode_s``, ``effort_weight``, ``privileged``, ``render_mode``).
    """

    _extra_options = ("task", "setpoint_deg")
    _episode_attrs = ("_k", "_setpoints", "_last_action", "_pid", "_ctl", "_hover_col", "_meas")

    def __init__(self, axis: str = "pitch", vehicle="anteos-p2a2", *, control: str = "command", gains=None,
                 task: str = "tracking", setpoint_max_deg: float = 10.0, setpoint_period_s: float = 2.0,
                 rate_limit_dps: float | None = None, controller=None, **kwargs):
        if axis not in _AXIS:
            raise UnknownNameError("rig axis", axis, _AXIS)
        if control not in CONTROLS:
            raise UnknownNameError("rig control", control, CONTROLS)
        self._check_task(task)
        if (controller is not None) != (control == "controller"):
            raise ConfigError("control='controller' flies the controller given as controller=", field="controller",
                              expected="a controller with control='controller' and none otherwise", got=controller)
        if not 0 < setpoint_max_deg < ANGLE_BOUND_DEG:
            raise ConfigError(field="setpoint_max_deg", expected=f"0 < value < {ANGLE_BOUND_DEG}", got=setpoint_max_deg)
        if not setpoint_period_s > 0:
            raise ConfigError(field="setpoint_period_s", expected="a period > 0 s", got=setpoint_period_s)
        scene, self._cmd_index, self._angle, self._rate, self._true_index = _AXIS[axis]
        super().__init__(scene, vehicle, **kwargs)
        self.axis = axis
        self.control = control
        self.task = task
        self.setpoint_max_deg = float(setpoint_max_deg)
        self.setpoint_period_s = float(setpoint_period_s)
        self.u_limit_pct = float(self.base_vehicle.command_limit_pct)
        self.gains = resolve_gains(self.base_vehicle, gains)
        self._ctl = None
        if control in ("command", "controller"):
            bound, unit = self.u_limit_pct, "%"
        else:
            if rate_limit_dps is None:
                rate_limit_dps = self.base_vehicle.commands.rate_limit_dps
            if not rate_limit_dps > 0:
                raise ConfigError(field="rate_limit_dps", expected="a limit > 0 deg/s", got=rate_limit_dps)
            bound, unit = float(rate_limit_dps), "deg/s"
        self._set_actions([-bound], [bound], [unit])
        lo = [-ANGLE_BOUND_DEG, -RATE_BOUND_DPS, -ANGLE_BOUND_DEG, -bound]
        if self.privileged:
            lo += [-ANGLE_BOUND_DEG, -RATE_BOUND_DPS]
        self.observation_space = box(lo, [-x for x in lo])
        self._pid = DiscretePID(self.gains[axis].inner, self.control_dt_s, -self.u_limit_pct, self.u_limit_pct)
        if controller is not None:
            spec = as_controller_spec(controller)
            cmd = ("u_lat", "u_lon")[self._cmd_index - 1]
            if spec.outputs != (cmd,):
                raise ConfigError(f"the {axis} rig's controller sets its axis command", field="controller.outputs",
                                  expected=[cmd], got=list(spec.outputs))
            self._ctl = StateSpaceController(spec, self.control_dt_s, [self.u_limit_pct])
            self._ctl_out, self._ctl_ref = cmd, f"{self._angle}_ref"
        self._setpoints = np.zeros(self.n_steps + 1)
        self._last_action = 0.0
        self._meas = None

    @staticmethod
    def _check_task(task):
        if task not in TASKS:
            raise UnknownNameError("rig task", str(task), TASKS)

    # ------------------------------------------------------------------ episode
    def _start_episode(self, options: dict) -> None:
        task = options.get("task", self.task)
        self._check_task(task)
        n = self.n_steps + 1
        if "setpoint_deg" in options:
            sp = float(options["setpoint_deg"])
            if not abs(sp) < ANGLE_BOUND_DEG:
                raise ConfigError(field="setpoint_deg", expected=f"|value| < {ANGLE_BOUND_DEG} deg", got=sp)
            self._setpoints = np.full(n, sp)
        elif task == "tracking":
            per = max(1, int(round(self.setpoint_period_s / self.control_dt_s)))
            levels = self.np_random.uniform(-self.setpoint_max_deg, self.setpoint_max_deg, n // per + 1)
            self._setpoints = np.repeat(levels, per)[:n]
        else:
            self._setpoints = np.zeros(n)
        self._last_action = 0.0
        self._pid.reset()
        if self._ctl is not None:
            self._ctl.reset()
        self._hover_col = self.vehicle.hover_collective_pct  # a property computed from the spec: once per episode

    # ------------------------------------------------------------------ stepping
    def _apply(self, action) -> float:
        a = float(action[0])
        if self.control == "command":
            u = a
        elif self.control == "controller":
            sig = dict(self._meas)
            sig[self._ctl_ref] = self._setpoint()
            lim = self.u_limit_pct
            u = min(max(self._ctl.step(self.sim.time, sig)[self._ctl_out] + a, -lim), lim)
        else:
            u = self._pid.step(a, self._meas[self._rate])
        cmd = [self._hover_col, 0.0, 0.0, 0.0]
        cmd[self._cmd_index] = u
        sim = self.sim
        # u is already within the command limit (action bounds / PID saturation): mix directly, skipping
        # set_commands' re-clipping, which costs more than the rest of this method
        sim.commands_pct = cmd
        sim.set_rotor_commands(sim.mixer.mix(*cmd))
        self._last_action = a
        return (u / self.u_limit_pct) ** 2

    def _setpoint(self) -> float:
        # past the episode end (an env stepped on after truncation) the last set-point holds
        return self._setpoints[min(self._k, self.n_steps)]

    def _true(self):
        # the airframe angle on a 1-DoF rig is the bearing plus the mount hinge (both on the rig axis, signed so
        # that positive is nose up / right side down): exact and far cheaper than the quaternion conversion
        s = self.sim
        m, d = s.model, s.data
        qa, va = m.jnt_qposadr, m.jnt_dofadr
        ang = d.qpos[qa[s._bearing]] + d.qpos[qa[s._mount]]
        rate = d.qvel[va[s._bearing]] + d.qvel[va[s._mount]]
        return math.degrees(ang), math.degrees(rate)

    def _reward(self, effort: float) -> float:
        err = (self._true()[0] - self._setpoint()) / ERROR_SCALE_DEG
        return -(err * err) - self.effort_weight * effort

    def _observe(self) -> np.ndarray:
        self._meas = m = self.sim.measure()
        obs = [m[self._angle], m[self._rate], self._setpoint(), self._last_action]
        if self.privileged:
            obs += list(self._true())
        return clip_obs(self.observation_space, obs)

    def _info(self) -> dict:
        return {"t": self.sim.time, "setpoint_deg": float(self._setpoint())}


__all__ = ["RigEnv", "CONTROLS", "TASKS"]
