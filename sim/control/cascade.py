"""Cascade attitude control: outer PD on the angle -> rate set-point, inner PID on the rate -> axis command.

This is the ANTEOS architecture (reference 000): 0.02 s cycle, outer PD on pitch angle (deg) giving a pitch-rate
set-point (deg/s, saturated at +-150 deg/s in the rope-pull test), inner PID on pitch rate giving the pitch
control variable (%, saturated at +-30 % on the P2-A2 and +-40 % on the A2-MINI/B). Both loops are
:class:`~rotorlab.sim.control.pid.DiscretePID` in the forward-Euler form the published gains were tuned in.

Sign conventions follow :mod:`rotorlab.sim.control.mixer`: a positive axis command produces a positive moment,
so a positive command raises the angle.
"""

from __future__ import annotations

import math

from rotorlab.errors import ConfigError
from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.sim.control.pid import DiscretePID

#: Yaw axis used when a gain set has no ``[yaw.*]`` tables: heading hold (P, deg/s per deg) -> yaw-rate PI
#: (% per deg/s). Conservative: yaw authority of a rotorcraft is small and the published work does not tune it.
DEFAULT_YAW_GAINS = AxisGains(outer=LoopGains(kp=2.0), inner=LoopGains(kp=0.4, ki=0.8))


def wrap_deg(angle_deg: float) -> float:
    """Wrap an angle to [-180, 180) deg."""
    return (angle_deg + 180.0) % 360.0 - 180.0


class CascadeAxis:
    """One attitude axis: outer PD on angle -> rate set-point (saturated), inner PID on rate -> command (saturated).

    Parameters
    ----------
    outer, inner : rotorlab.gains.LoopGains
        Outer loop in deg/s per deg, inner loop in % per deg/s.
    dt : float
        Sample time, s.
    rate_limit_dps : float
        Saturation of the rate set-point, deg/s.
    u_limit_pct : float
        Saturation of the axis command, %.
    antiwindup : {'clamp', 'backcalc', None}
        Anti-windup of the inner PID (the outer PD has no integral).
    wrap : bool
        Treat the angle as a heading: the measurement is unwrapped across +-180 deg and the set-point is taken
        on the shortest way round, so the loop never sees a 360 deg jump.
    """

    __slots__ = ("outer", "inner", "rate_limit_dps", "u_limit_pct", "wrap", "_ang_u", "_ang_prev")

    def __init__(self, outer: LoopGains, inner: LoopGains, dt: float, rate_limit_dps: float, u_limit_pct: float,
                 antiwindup: str | None = "clamp", wrap: bool = False):
        if not rate_limit_dps > 0:
            raise ConfigError(field="rate_limit_dps", expected="a limit > 0 deg/s", got=rate_limit_dps)
        if not u_limit_pct > 0:
            raise ConfigError(field="u_limit_pct", expected="a limit > 0 %", got=u_limit_pct)
        self.rate_limit_dps = float(rate_limit_dps)
        self.u_limit_pct = float(u_limit_pct)
        self.outer = DiscretePID(outer, dt, -self.rate_limit_dps, self.rate_limit_dps, antiwindup=antiwindup)
        self.inner = DiscretePID(inner, dt, -self.u_limit_pct, self.u_limit_pct, antiwindup=antiwindup)
        self.wrap = bool(wrap)
        self._ang_u = None
        self._ang_prev = 0.0

    def reset(self, u0: float = 0.0, angle0: float | None = None, rate0: float | None = None) -> None:
        """Bumpless start: with ``angle0``/``rate0`` the loops start at rest holding ``angle0`` with output ``u0``."""
        self._ang_u = None if angle0 is None else float(angle0)
        self._ang_prev = 0.0 if angle0 is None else float(angle0)
        self.outer.reset(0.0, angle0)
        self.inner.reset(u0, None if rate0 is None else rate0, None if rate0 is None else 0.0)

    def set_gains(self, outer: LoopGains, inner: LoopGains) -> None:
        """Bumpless gain switch of both loops (see :meth:`DiscretePID.set_gains`)."""
        self.outer.set_gains(outer)
        self.inner.set_gains(inner)

    def step(self, angle_ref: float, angle: float, rate: float, u_ff: float = 0.0) -> tuple[float, float]:
        """One sample. Angles in deg, rate in deg/s; ``u_ff`` is added to the command before the saturation.

        Returns ``(u, rate_ref)``: the saturated command (%) and the saturated rate set-point (deg/s).
        """
        if self.wrap:
            if self._ang_u is None:
                self._ang_u = angle
            else:
                self._ang_u += (angle - self._ang_prev + 180.0) % 360.0 - 180.0
            self._ang_prev = angle
            angle = self._ang_u
            angle_ref = angle + (angle_ref - angle + 180.0) % 360.0 - 180.0
        rate_ref = self.outer.step(angle_ref, angle)
        return self.inner.step(rate_ref, rate, u_ff), rate_ref


class AttitudeController:
    """Roll, pitch and yaw cascades with an optional in-flight gain schedule.

    Parameters
    ----------
    gains : rotorlab.gains.GainSet
        Roll and pitch (and yaw) gains. Without a yaw axis, :data:`DEFAULT_YAW_GAINS` (heading P -> yaw-rate PI).
    dt : float
        Sample time, s.
    limits : rotorlab.vehicles.spec.CommandLimits
        Rate set-point and command saturations of roll/pitch and yaw (the vehicle's ``commands``).
    antiwindup : {'clamp', 'backcalc', None}
    schedule : list of (t_s, GainSet), optional
        Gain sets switched in (bumplessly) at time ``t_s`` (s), e.g. standard -> optimal in flight as in the
        A2-MINI/B flight test. Yaw switches only if the new set has a yaw axis.
    """

    def __init__(self, gains: GainSet, dt: float, limits, antiwindup: str | None = "clamp", schedule=None):
        if not isinstance(gains, GainSet):
            raise ConfigError(field="gains", expected="a rotorlab.gains.GainSet", got=type(gains).__name__)
        self.gains = gains
        yaw = gains.axes.get("yaw", DEFAULT_YAW_GAINS)
        lim = limits
        self.roll = CascadeAxis(gains["roll"].outer, gains["roll"].inner, dt, lim.rate_limit_dps, lim.limit_pct,
                                antiwindup)
        self.pitch = CascadeAxis(gains["pitch"].outer, gains["pitch"].inner, dt, lim.rate_limit_dps, lim.limit_pct,
                                 antiwindup)
        self.yaw = CascadeAxis(yaw.outer, yaw.inner, dt, lim.yaw_rate_limit_dps, lim.yaw_limit_pct, antiwindup,
                               wrap=True)
        sched = sorted(schedule or [], key=lambda e: e[0])
        for t_s, gs in sched:
            if not isinstance(gs, GainSet) or not math.isfinite(t_s):
                raise ConfigError(field="schedule", expected="a list of (t_s, GainSet)", got=(t_s, gs))
        self._schedule = sched
        self._next = 0
        #: time of the next scheduled switch (inf when none): one comparison per tick for the caller
        self.t_next_switch = sched[0][0] if sched else math.inf

    def reset(self) -> None:
        """Zero every loop state (the gain schedule is not rewound)."""
        for ax in (self.roll, self.pitch, self.yaw):
            ax.reset()

    def _switch(self, gs: GainSet) -> None:
        self.gains = gs
        self.roll.set_gains(gs["roll"].outer, gs["roll"].inner)
        self.pitch.set_gains(gs["pitch"].outer, gs["pitch"].inner)
        if "yaw" in gs.axes:
            self.yaw.set_gains(gs["yaw"].outer, gs["yaw"].inner)

    def apply_schedule(self, t: float) -> None:
        """Switch to every scheduled gain set whose time has come (bumpless)."""
        while self._next < len(self._schedule) and t >= self._schedule[self._next][0]:
            self._switch(self._schedule[self._next][1])
            self._next += 1
        self.t_next_switch = self._schedule[self._next][0] if self._next < len(self._schedule) else math.inf

    def step(self, t: float, phi_ref: float, theta_ref: float, psi_ref: float, phi: float, theta: float,
             psi: float, p: float, q: float, r: float, u_ff_lat: float = 0.0, u_ff_lon: float = 0.0,
             u_ff_yaw: float = 0.0):
        """One sample at time ``t`` (s). Angles deg, rates deg/s.

        Returns ``(u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref)``: roll, pitch and yaw commands (%) and the rate
        set-points (deg/s).
        """
        if t >= self.t_next_switch:
            self.apply_schedule(t)
        u_lat, p_ref = self.roll.step(phi_ref, phi, p, u_ff_lat)
        u_lon, q_ref = self.pitch.step(theta_ref, theta, q, u_ff_lon)
        u_yaw, r_ref = self.yaw.step(psi_ref, psi, r, u_ff_yaw)
        return u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref
