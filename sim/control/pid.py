"""Discrete two-degree-of-freedom PID, sample by sample, in the form the published gains were tuned in.

The control law (units follow the loop: deg, deg/s, %) is the parallel 2-DoF PID

    u = kp (b r - y) + ki I(z) (r - y) + kd / (tf + I(z)) (c r - y),    I(z) = dt / (z - 1),

with the forward-Euler integrator ``I(z)`` for both the integral and the derivative filter (MATLAB's
``pid(..., 'IFormula', 'ForwardEuler', 'DFormula', 'ForwardEuler')``). Unsaturated, the output equals
:func:`rotorlab.lti.pid2_ss` simulated on the same samples to round-off (tests/test_control_pid.py).

States (both advance by forward Euler, so the output at tick k depends on inputs up to k-1 only through them):

* ``xi``: the integral term itself, ``xi[k+1] = xi[k] + ki dt e[k]`` with ``e = r - y``;
* ``xd``: the integrated derivative-filter output, ``ud = (kd (c r - y) - xd) / tf``, ``xd[k+1] = xd[k] + dt ud[k]``.
  The filter pole is at ``z = 1 - dt/tf``: stable for ``tf > dt/2``.

With ``c = 1`` the derivative acts on the error, so a set-point step of size ``dr`` moves the first output
by ``(kp b + kd/tf) dr`` (derivative kick); ``c = 0`` puts the derivative on the measurement only.
"""

from __future__ import annotations

import math

from rotorlab.errors import ConfigError
from rotorlab.gains import LoopGains

ANTIWINDUP = ("clamp", "backcalc", None)


def _check_gains(gains: LoopGains, dt: float) -> None:
    if not isinstance(gains, LoopGains):
        raise ConfigError(field="gains", expected="a rotorlab.gains.LoopGains", got=type(gains).__name__)
    if gains.kd != 0.0 and not gains.tf > dt / 2.0:
        raise ConfigError("the forward-Euler derivative filter is unstable", field="tf",
                          expected=f"tf > dt/2 = {dt / 2.0} s when kd != 0", got=gains.tf)


class DiscretePID:
    """Parallel 2-DoF PID with output saturation and anti-windup, one call per sample.

    Parameters
    ----------
    gains : rotorlab.gains.LoopGains
        ``kp, ki, kd, tf (s), b, c``.
    dt : float
        Sample time, s.
    u_min, u_max : float
        Output saturation (same unit as ``u``); ``-inf``/``inf`` for none.
    antiwindup : {'clamp', 'backcalc', None}
        ``'clamp'``: conditional integration, the integral is frozen while the output is saturated and the
        error would drive it further into saturation. ``'backcalc'``: back-calculation, the integral is
        fed ``(u_sat - u_unsat) / tt`` so it tracks the saturated output with time constant ``tt``.
        ``None``: the integral keeps integrating the error (windup), for comparison.
    tracking_time_s : float, optional
        Back-calculation time constant ``tt``. Default ``sqrt(Ti Td)`` with ``Ti = kp/ki``, ``Td = kd/kp``
        (Astrom & Hagglund's rule), ``Ti`` for a PI; floored at ``dt`` because the forward-Euler tracking
        update ``xi += dt/tt (u_sat - u)`` overshoots for ``dt/tt > 1``.
    """

    __slots__ = ("dt", "u_min", "u_max", "antiwindup", "_tt_user", "kp", "ki", "kd", "tf", "b", "c", "gains",
                 "_kidt", "_kd_tf", "_inv_tf", "_aw_gain", "_aw", "xi", "xd", "u", "u_unsat", "_r", "_y")

    def __init__(self, gains: LoopGains, dt: float, u_min: float = -math.inf, u_max: float = math.inf,
                 antiwindup: str | None = "clamp", tracking_time_s: float | None = None):
        if not dt > 0:
            raise ConfigError(field="dt", expected="a sample time > 0 s", got=dt)
        if antiwindup not in ANTIWINDUP:
            raise ConfigError(field="antiwindup", expected=f"one of {ANTIWINDUP}", got=antiwindup)
        if not u_min < u_max:
            raise ConfigError(field="u_min/u_max", expected="u_min < u_max", got=(u_min, u_max))
        if tracking_time_s is not None and not tracking_time_s > 0:
            raise ConfigError(field="tracking_time_s", expected="a time constant > 0 s", got=tracking_time_s)
        self.dt = float(dt)
        self.u_min = float(u_min)
        self.u_max = float(u_max)
        self.antiwindup = antiwindup
        self._tt_user = tracking_time_s
        self._load(gains)
        self.reset()

    def _load(self, gains: LoopGains) -> None:
        _check_gains(gains, self.dt)
        self.gains = gains
        # plain Python floats: numpy scalars make every arithmetic op several times slower in this hot path
        self.kp, self.ki, self.kd = float(gains.kp), float(gains.ki), float(gains.kd)
        self.tf, self.b, self.c = float(gains.tf), float(gains.b), float(gains.c)
        self._kidt = self.ki * self.dt
        has_d = self.kd != 0.0
        self._kd_tf = self.kd / self.tf if has_d else 0.0
        self._inv_tf = 1.0 / self.tf if has_d else 0.0
        if self._tt_user is not None:
            tt = self._tt_user
        elif self.ki > 0.0 and self.kp != 0.0:
            ti = self.kp / self.ki
            tt = math.sqrt(ti * self.kd / self.kp) if has_d else ti
        else:
            tt = self.dt
        self._aw_gain = self.dt / max(tt, self.dt)
        # integer code of the integral update, 0 when there is no integral: one cheap test per tick
        self._aw = 0 if self._kidt == 0.0 else {"clamp": 1, "backcalc": 2, None: 3}[self.antiwindup]

    def reset(self, u0: float = 0.0, y0: float | None = None, r0: float | None = None) -> None:
        """Re-initialise the states, bumplessly when ``y0`` is given.

        With ``y0`` (and ``r0``, default ``y0``) the derivative filter starts at rest for that input and the
        integral absorbs the rest, so the first output for ``(r0, y0)`` is exactly ``u0``. Without ``y0`` the
        derivative state is zero and the integral starts at ``u0``. For a PD (``ki = 0``) the integral state
        is not integrated further: it stays as the constant offset ``u0 - kp (b r0 - y0)`` (manual reset).
        """
        self.u = self.u_unsat = float(u0)
        if y0 is None:
            self.xd = 0.0
            self.xi = float(u0)
            self._r = self._y = 0.0
            return
        y0 = float(y0)
        r0 = y0 if r0 is None else float(r0)
        self.xd = self.kd * (self.c * r0 - y0)
        self.xi = float(u0) - self.kp * (self.b * r0 - y0)
        self._r, self._y = r0, y0

    def set_gains(self, gains: LoopGains) -> None:
        """Switch gains in flight, without a bump where the new loop integrates.

        The derivative state is set so the new derivative term continues the old one. With integral action
        (``ki > 0``) the integral absorbs the difference of the proportional terms: the output the old
        controller would give next tick if the inputs stayed at the last ``(r, y)`` is kept, so for constant
        inputs the output is exactly continuous, with moving inputs the jump is only the new-vs-old gain
        difference applied to the change of the inputs over one tick, and the integration then takes the
        absorbed difference out. Without integral action (the cascade's outer PD) the integral state is a
        constant offset that nothing ever takes out: absorbing the difference there would leave the loop
        holding ``(kp_old - kp_new) (b r - y)`` at the switch as a permanent bias (an angle offset of that over
        ``kp_new`` once the rate loop settles), so the offset is kept as it was and the proportional term
        switches with the gains, a bump of ``(kp_new - kp_old) (b r - y)``.
        """
        r, y = self._r, self._y
        ud_old = (self.kd * (self.c * r - y) - self.xd) / self.tf if self.kd != 0.0 else 0.0
        u_next = self.kp * (self.b * r - y) + self.xi + ud_old
        self._load(gains)
        if self.kd != 0.0:
            self.xd = self.kd * (self.c * r - y) - self.tf * ud_old
            ud_new = ud_old
        else:
            self.xd = 0.0
            ud_new = 0.0
        if self._kidt != 0.0:
            self.xi = u_next - self.kp * (self.b * r - y) - ud_new

    def step(self, r: float, y: float, u_ff: float = 0.0) -> float:
        """One sample: set-point ``r``, measurement ``y``, additive feed-forward ``u_ff`` (applied before the
        saturation, so anti-windup sees it: use it for command excitation). Returns the saturated output."""
        if self._kd_tf != 0.0:
            ud = self._kd_tf * (self.c * r - y) - self.xd * self._inv_tf
            self.xd += self.dt * ud
            u = self.kp * (self.b * r - y) + self.xi + ud + u_ff
        else:
            u = self.kp * (self.b * r - y) + self.xi + u_ff
        hi, lo = self.u_max, self.u_min
        us = hi if u > hi else (lo if u < lo else u)
        aw = self._aw
        if aw:
            e = r - y
            if aw == 1:
                # conditional integration: freeze only when integrating would push further into saturation
                if not ((u > hi and e > 0.0) or (u < lo and e < 0.0)):
                    self.xi += self._kidt * e
            elif aw == 2:
                self.xi += self._kidt * e + self._aw_gain * (us - u)
            else:
                self.xi += self._kidt * e
        self.u_unsat = u
        self.u = us
        self._r = r
        self._y = y
        return us
