"""Attitude supervisor for quasi-open-loop identification experiments.

In the published PRBS campaigns (reference 000) the nominal attitude and position controllers were off and
"a supervision task enforcing attitude limits (+-20 deg) was left active". Its law is not published; this is
the simplest one with that behaviour: silent inside a dead band, a restoring PD outside it.

    |angle| <= engage_frac * limit:  u = 0
    otherwise:                       u = -(kp (angle - sign(angle) engage_frac limit) + kd rate),
                                     kept restoring (never pushes towards the limit) and within +-u_limit.

The output is added to the axis command (%); a positive command raises the angle. The rate term switches in
with the band, so the first supervised sample steps by ``-kd rate``: a restoring kick, which is what a limit
supervisor is for. Inside the band the experiment stays open loop, so the identification data there carry no
supervisor feedback.
"""

from __future__ import annotations

from rotorlab.errors import ConfigError


class Supervisor:
    """Attitude-limit supervisor for one axis.

    Parameters
    ----------
    limit_deg : float
        Attitude limit, deg (published: 20).
    engage_frac : float
        Fraction of the limit where the supervisor starts acting, in (0, 1).
    kp : float
        Restoring gain on the excess angle, % per deg.
    kd : float
        Rate damping while engaged, % per deg/s.
    u_limit_pct : float
        Saturation of the supervisor output, %.
    """

    __slots__ = ("limit_deg", "engage_frac", "kp", "kd", "u_limit_pct", "_band", "active", "u")

    def __init__(self, limit_deg: float = 20.0, engage_frac: float = 0.75, kp: float = 4.0, kd: float = 0.5,
                 u_limit_pct: float = 30.0):
        if not limit_deg > 0:
            raise ConfigError(field="limit_deg", expected="a limit > 0 deg", got=limit_deg)
        if not 0.0 < engage_frac < 1.0:
            raise ConfigError(field="engage_frac", expected="a fraction in (0, 1)", got=engage_frac)
        if kp < 0 or kd < 0 or not u_limit_pct > 0:
            raise ConfigError(field="kp/kd/u_limit_pct", expected="kp >= 0, kd >= 0, u_limit_pct > 0",
                              got=(kp, kd, u_limit_pct))
        self.limit_deg = float(limit_deg)
        self.engage_frac = float(engage_frac)
        self.kp, self.kd, self.u_limit_pct = float(kp), float(kd), float(u_limit_pct)
        self._band = self.engage_frac * self.limit_deg
        self.active = False
        self.u = 0.0

    def reset(self) -> None:
        self.active = False
        self.u = 0.0

    def step(self, angle_deg: float, rate_dps: float) -> float:
        """Supervisor command (%) for the measured angle (deg) and rate (deg/s)."""
        band = self._band
        if angle_deg > band:
            u = -(self.kp * (angle_deg - band) + self.kd * rate_dps)
            u = min(0.0, max(-self.u_limit_pct, u))
        elif angle_deg < -band:
            u = -(self.kp * (angle_deg + band) + self.kd * rate_dps)
            u = max(0.0, min(self.u_limit_pct, u))
        else:
            u = 0.0
        self.active = u != 0.0
        self.u = u
        return u
