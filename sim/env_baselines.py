"""Our flight software as policies for the Gymnasium envs: the bar an RL agent has to beat.

Both read only the env's observation (IMU, set-point / target), exactly as an agent does, and return the
normalised action an agent returns (``env.normalize_action`` of the physical command); they run the
vehicle's cascade (:class:`~rotorlab.sim.control.cascade.CascadeAxis` on the rig,
:class:`~rotorlab.sim.control.flight_software.FlightSoftware` in position mode in flight) with its gain set.
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.sim.control.cascade import CascadeAxis
from rotorlab.sim.control.flight_software import FlightSoftware
from rotorlab.sim.control.position import PositionGains
from rotorlab.sim.runner import resolve_gains
from rotorlab.sim.simulator import vehicle_mixer


class RigPIDPolicy:
    """Cascade PID for :class:`~rotorlab.sim.env_rig.RigEnv` in ``command`` mode: angle PD -> rate set-point
    (+-``rate_limit_dps``, default the vehicle's) -> rate PID -> axis command (%), the published architecture and
    gains."""

    def __init__(self, env, gains=None, rate_limit_dps: float | None = None):
        e = env.unwrapped
        if getattr(e, "control", None) != "command":
            raise ConfigError(field="env.control", expected="a rig env in 'command' mode", got=getattr(e, "control", None))
        self.env = e
        g = resolve_gains(e.base_vehicle, gains if gains is not None else e.gains)[e.axis]
        if rate_limit_dps is None:
            rate_limit_dps = e.base_vehicle.commands.rate_limit_dps
        self.axis = CascadeAxis(g.outer, g.inner, e.control_dt_s, rate_limit_dps, e.u_limit_pct)

    def reset(self) -> None:
        self.axis.reset()

    def __call__(self, obs) -> np.ndarray:
        angle, rate, setpoint = float(obs[0]), float(obs[1]), float(obs[2])
        u, _ = self.axis.step(setpoint, angle, rate)
        return self.env.normalize_action([u])


class HoverPIDPolicy:
    """Position hold for :class:`~rotorlab.sim.env_hover.HoverEnv` in ``commands`` mode: the flight software
    in position mode (position -> attitude set-points -> attitude cascade, altitude hold)."""

    _MEAS = ("phi", "theta", "psi", "p", "q", "r", "ax", "ay", "az", "x", "y", "z", "vx", "vy", "vz")

    def __init__(self, env, gains=None):
        e = env.unwrapped
        if getattr(e, "control", None) != "commands":
            raise ConfigError(field="env.control", expected="a hover env in 'commands' mode",
                              got=getattr(e, "control", None))
        self.env = e
        v = e.base_vehicle
        pos = PositionGains.for_vehicle(v.mass_kg, v.hover_collective_pct, v.thrust_exponent)
        self.dt = e.control_dt_s
        self.fs = FlightSoftware(resolve_gains(v, gains if gains is not None else e.gains), vehicle_mixer(v),
                                 dt=self.dt, mode="position", limits=v.commands, position_gains=pos)
        self.reset()

    def reset(self) -> None:
        self.fs.reset()
        self._t = 0.0

    def __call__(self, obs) -> np.ndarray:
        meas = dict(zip(self._MEAS, map(float, obs[:15])))
        self.fs.set_reference(x_ref=float(obs[15]), y_ref=float(obs[16]), z_ref=float(obs[17]))
        out = self.fs.step(self._t, meas)
        self._t += self.dt
        return self.env.normalize_action([out["u_col"], out["u_lat"], out["u_lon"], out["u_yaw"]])


def episode_return(env, policy, seed: int, options: dict | None = None) -> tuple[float, int, bool]:
    """Run one episode of ``policy`` on ``env``; returns ``(return, steps, terminated)``."""
    obs, _ = env.reset(seed=seed, options=options)
    policy.reset()
    total, steps = 0.0, 0
    while True:
        obs, r, term, trunc, _ = env.step(policy(obs))
        total += r
        steps += 1
        if term or trunc:
            return total, steps, bool(term)


__all__ = ["RigPIDPolicy", "HoverPIDPolicy", "episode_return"]
