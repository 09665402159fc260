"""Vectorised flight software: the attitude cascade of :mod:`rotorlab.sim.control.cascade` over many simulations.

Every signal is a numpy array of shape ``(nsim,)`` and every gain may differ per simulation. The arithmetic is
written in the same order as the scalar :class:`~rotorlab.sim.control.pid.DiscretePID` (forward-Euler
integral and derivative filter, conditional-integration anti-windup, output saturation), so a batched run
reproduces the scalar flight software to round-off (bit for bit on the operations used here; only the angle
conversion from the IMU quaternion may differ in the last ulp, where numpy's vectorised ``arcsin``/``arctan2``
differ from libm's).

Only the parts that the rig scenarios need are vectorised: the cascade mode without gain schedule, excitation
or plug-ins, and the open-loop mode's attitude supervisor.
"""

from __future__ import annotations

import math

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.gains import GainSet, LoopGains
from rotorlab.sim.control.cascade import DEFAULT_YAW_GAINS
from rotorlab.sim.control.supervisor import Supervisor

_FIELDS = ("kp", "ki", "kd", "tf", "b", "c")


def _gain_arrays(gains, n: int) -> dict:
    """``{'kp': (n,), ...}`` from one LoopGains (all simulations) or a sequence of n of them."""
    if isinstance(gains, LoopGains):
        gains = [gains] * n
    gains = list(gains)
    if len(gains) != n:
        raise ConfigError(field="gains", expected=f"one LoopGains or {n} of them", got=len(gains))
    for g in gains:
        if not isinstance(g, LoopGains):
            raise ConfigError(field="gains", expected="rotorlab.gains.LoopGains", got=type(g).__name__)
    return {f: np.array([float(getattr(g, f)) for g in gains]) for f in _FIELDS}


class VectorPID:
    """Parallel 2-DoF PID over ``n`` simulations, as :class:`~rotorlab.sim.control.pid.DiscretePID` with
    ``antiwindup='clamp'`` (conditional integration).

    Parameters
    ----------
    gains : LoopGains or sequence of n LoopGains
        ``kp, ki, kd, tf (s), b, c``, per simulation when a sequence.
    n : int
        Number of simulations.
    dt : float
        Sample time, s.
    u_min, u_max : float
        Output saturation (common to all simulations).
    """

    def __init__(self, gains, n: int, dt: float, u_min: float = -np.inf, u_max: float = np.inf):
        if not dt > 0:
            raise ConfigError(field="dt", expected="a sample time > 0 s", got=dt)
        if not u_min < u_max:
            raise ConfigError(field="u_min/u_max", expected="u_min < u_max", got=(u_min, u_max))
        g = _gain_arrays(gains, n)
        has_d = g["kd"] != 0.0
        bad = has_d & ~(g["tf"] > dt / 2.0)
        if bad.any():
            i = int(np.argmax(bad))
            raise ConfigError(f"the forward-Euler derivative filter of simulation {i} is unstable", field="tf",
                              expected=f"tf > dt/2 = {dt / 2.0} s when kd != 0", got=float(g["tf"][i]))
        self.n, self.dt = int(n), float(dt)
        self.u_min, self.u_max = float(u_min), float(u_max)
        self.kp, self.ki, self.kd, self.tf, self.b, self.c = (g[f] for f in _FIELDS)
        self._kidt = self.ki * self.dt
        # kd = 0: both factors zero, so the derivative term is exactly 0 and its state stays 0, as the scalar
        # controller's skipped branch
        safe_tf = np.where(has_d, self.tf, 1.0)
        self._kd_tf = np.where(has_d, self.kd / safe_tf, 0.0)
        self._inv_tf = np.where(has_d, 1.0 / safe_tf, 0.0)
        self.reset()

    def reset(self) -> None:
        """Zero states (the scalar ``reset()`` without a bumpless start)."""
        self.xi = np.zeros(self.n)
        self.xd = np.zeros(self.n)
        self.u = np.zeros(self.n)

    def step(self, r, y, u_ff=0.0) -> np.ndarray:
        """One sample for every simulation; returns the saturated output ``(n,)``."""
        ud = self._kd_tf * (self.c * r - y) - self.xd * self._inv_tf
        self.xd = self.xd + self.dt * ud
        u = self.kp * (self.b * r - y) + self.xi + ud + u_ff
        hi, lo = self.u_max, self.u_min
        us = np.minimum(np.maximum(u, lo), hi)
        e = r - y
        # conditional integration: freeze only where integrating would push further into saturation
        freeze = ((u > hi) & (e > 0.0)) | ((u < lo) & (e < 0.0))
        self.xi = np.where(freeze, self.xi, self.xi + self._kidt * e)
        self.u = us
        return us


class VectorCascadeAxis:
    """Outer PD on the angle -> saturated rate set-point -> inner PID on the rate -> saturated command, for n
    simulations (:class:`~rotorlab.sim.control.cascade.CascadeAxis`)."""

    def __init__(self, outer, inner, n: int, dt: float, rate_limit_dps: float, u_limit_pct: float,
                 wrap: bool = False):
        if not rate_limit_dps > 0:
            raise ConfigError(field="rate_limit_dps", expected="a limit > 0 deg/s", got=rate_limit_dps)
        if not u_limit_pct > 0:
            raise ConfigError(field="u_limit_pct", expected="a limit > 0 %", got=u_limit_pct)
        self.outer = VectorPID(outer, n, dt, -float(rate_limit_dps), float(rate_limit_dps))
        self.inner = VectorPID(inner, n, dt, -float(u_limit_pct), float(u_limit_pct))
        self.wrap = bool(wrap)
        self.reset()

    def reset(self) -> None:
        self.outer.reset()
        self.inner.reset()
        self._ang_u = None
        self._ang_prev = None

    def step(self, angle_ref, angle, rate, u_ff=0.0) -> tuple[np.ndarray, np.ndarray]:
        """Returns ``(u, rate_ref)``: saturated commands (%) and rate set-points (deg/s), each ``(n,)``."""
        if self.wrap:
            if self._ang_u is None:
                self._ang_u = np.array(angle, dtype=float)
            else:
                self._ang_u = self._ang_u + ((angle - self._ang_prev + 180.0) % 360.0 - 180.0)
            self._ang_prev = angle
            angle = self._ang_u
            angle_ref = angle + (angle_ref - angle + 180.0) % 360.0 - 180.0
        rate_ref = self.outer.step(angle_ref, angle)
        return self.inner.step(rate_ref, rate, u_ff), rate_ref


def _axis_gains(gains, axis: str, n: int) -> tuple[list, list]:
    """Per-simulation (outer, inner) LoopGains lists of one axis from one GainSet or n of them."""
    sets = [gains] * n if isinstance(gains, GainSet) else list(gains)
    if len(sets) != n:
        raise ConfigError(field="gains", expected=f"one GainSet or {n} of them", got=len(sets))
    outer, inner = [], []
    for gs in sets:
        if not isinstance(gs, GainSet):
            raise ConfigError(field="gains", expected="rotorlab.gains.GainSet", got=type(gs).__name__)
        ax = gs.axes.get(axis, DEFAULT_YAW_GAINS) if axis == "yaw" else gs[axis]
        outer.append(ax.outer)
        inner.append(ax.inner)
    return outer, inner


class VectorAttitudeController:
    """Roll, pitch and yaw cascades for n simulations (:class:`~rotorlab.sim.control.cascade.AttitudeController`
    without gain schedule). ``gains``: one GainSet for all simulations or a sequence of n; ``limits``: the
    vehicle's :class:`~rotorlab.vehicles.spec.CommandLimits`."""

    #: no gain schedule: the flight software's switch test never fires
    t_next_switch = math.inf

    def __init__(self, gains, n: int, dt: float, limits):
        lim = limits
        self.roll = VectorCascadeAxis(*_axis_gains(gains, "roll", n), n, dt, lim.rate_limit_dps, lim.limit_pct)
        self.pitch = VectorCascadeAxis(*_axis_gains(gains, "pitch", n), n, dt, lim.rate_limit_dps, lim.limit_pct)
        self.yaw = VectorCascadeAxis(*_axis_gains(gains, "yaw", n), n, dt, lim.yaw_rate_limit_dps, lim.yaw_limit_pct,
                                     wrap=True)

    def reset(self) -> None:
        for ax in (self.roll, self.pitch, self.yaw):
            ax.reset()

    def step(self, phi_ref, theta_ref, psi_ref, phi, theta, psi, p, q, r):
        """Returns ``(u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref)``, each ``(n,)`` (%, deg/s)."""
        u_lat, p_ref = self.roll.step(phi_ref, phi, p)
        u_lon, q_ref = self.pitch.step(theta_ref, theta, q)
        u_yaw, r_ref = self.yaw.step(psi_ref, psi, r)
        return u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref


class VectorSupervisor:
    """The open-loop mode's attitude-limit supervisor (:class:`~rotorlab.sim.control.supervisor.Supervisor`)
    for n simulations, with the template's parameters."""

    def __init__(self, template: Supervisor | None = None):
        s = template or Supervisor()
        self.kp, self.kd, self.u_limit_pct = s.kp, s.kd, s.u_limit_pct
        self._band = s.engage_frac * s.limit_deg

    def reset(self) -> None:
        """Nothing to reset: the supervisor is a static map of angle and rate."""

    def step(self, angle_deg, rate_dps) -> np.ndarray:
        band, lim = self._band, self.u_limit_pct
        hi = np.minimum(0.0, np.maximum(-lim, -(self.kp * (angle_deg - band) + self.kd * rate_dps)))
        lo = np.maximum(0.0, np.minimum(lim, -(self.kp * (angle_deg + band) + self.kd * rate_dps)))
        return np.where(angle_deg > band, hi, np.where(angle_deg < -band, lo, 0.0))


__all__ = ["VectorPID", "VectorCascadeAxis", "VectorAttitudeController", "VectorSupervisor"]
