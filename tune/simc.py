"""Skogestad SIMC PID rules as a baseline for structured H-inf tuning.

Reference: S. Skogestad, "Simple analytic rules for model reduction and PID controller tuning",
J. Process Control 13 (2003) 291-309. The plant is reduced with the half rule to first-order-plus-delay
(FOPTD), second-order-plus-delay (SOPTD), integrating or double-integrating plus delay, and the SIMC
settings are converted from the series form ``kc (1 + 1/(tau_I s)) (1 + tau_D s)`` to the parallel form of
:class:`rotorlab.gains.LoopGains` (``kp = kc (1 + tau_D/tau_I)``, ``ki = kc/tau_I``, ``kd = kc tau_D``).
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.errors import DataError
from rotorlab.gains import LoopGains

__all__ = ["HalfRuleModel", "half_rule", "simc_pid"]


@dataclasses.dataclass(frozen=True)
class HalfRuleModel:
    """``k e^{-theta s} / (s^n_int (tau1 s + 1)(tau2 s + 1))`` from the half rule (``tau2 = 0`` for FOPTD).

    ``k`` is the gain of the remaining factors (for integrating plants: the slope ``k'``/``k''``).
    """

    k: float
    tau1_s: float
    tau2_s: float
    theta_s: float
    n_int: int


def _zero_factor(T0, tau0, theta):
    """Approximation of ``(T0 s + 1)/(tau0 s + 1)`` by a constant, the five cases of Skogestad (2003)
    eq. (11) as we read them (``tau0`` the closest larger lag, ``theta`` the delay so far)."""
    if T0 >= tau0 >= theta:
        return T0 / tau0
    if T0 >= theta >= tau0:
        return T0 / theta
    if theta >= T0:
        return 1.0
    if tau0 >= T0 >= 5 * theta:
        return T0 / tau0
    tt = min(tau0, 5 * theta)
    return (tt / tau0) / (tt / T0 - 1.0)


def half_rule(G, delay_s: float = 0.0, second_order: bool = False) -> HalfRuleModel:
    """Half-rule reduction of a continuous SISO plant (Skogestad 2003, sec. 3).

    Integrators (poles within 1e-9 of 0) are kept (at most two); stable real poles give time constants;
    a complex pair with natural frequency ``wn`` counts as two lags of ``1/wn``; RHP zeros ``(-T0 s + 1)``
    add ``T0`` to the delay; each LHP zero cancels the closest larger lag by eq. (11) of the paper.
    The largest neglected lag is split half to the delay, half to the last kept lag.

    Parameters
    ----------
    G : continuous SISO LTI model without delay (``delay_s`` holds the delay, s).
    second_order : keep two lags (SOPTD, for PID) instead of one (FOPTD, for PI).

    Returns
    -------
    HalfRuleModel
        Gain, one or two time constants, delay and the number of integrators.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> m = tune.half_rule(ct.tf([1.0], [1, 3, 2]))     # 1 / ((s + 1)(s + 2)): lags 1 s and 0.5 s
    >>> float(m.tau1_s), float(m.theta_s)             # half of the neglected 0.5 s to each
    (1.25, 0.25)
    """
    if not isinstance(G, (ct.StateSpace, ct.TransferFunction)):
        raise DataError(f"the plant must be a control.StateSpace or TransferFunction; got {type(G).__name__}")
    if lti.is_discrete(G):
        raise DataError("the half rule needs a continuous model; convert with rotorlab.lti.d2c_zoh first")
    if G.ninputs != 1 or G.noutputs != 1:
        raise DataError(f"simc needs a SISO plant; got {G.noutputs}x{G.ninputs}")
    # a transfer function is used as given: a state-space round trip adds spurious far-away zeros
    tf = G if isinstance(G, ct.TransferFunction) else ct.tf(G)
    num = np.asarray(tf.num[0][0], float)
    den = np.asarray(tf.den[0][0], float)
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise DataError("the plant model contains NaN or inf entries")
    num = num[np.argmax(np.abs(num) > 1e-12 * np.abs(num).max()):] if np.any(num) else num
    den = np.trim_zeros(den, "f")
    poles, zeros = np.roots(den), np.roots(num)
    n_int = int(np.sum(np.abs(poles) < 1e-9))
    if n_int > 2:
        raise DataError(f"SIMC covers at most two integrators; the plant has {n_int}")
    poles = poles[np.abs(poles) >= 1e-9]
    if np.any(poles.real > 0):
        raise DataError("SIMC rules need a stable plant apart from integrators; got unstable poles "
                        f"{poles[poles.real > 0]}")
    # gain of the factored form: the low-frequency slope k / s^n_int
    den_rest = np.polydiv(den, np.r_[1.0, np.zeros(n_int)])[0] if n_int else den
    k = float(np.polyval(num, 0.0) / np.polyval(den_rest, 0.0))
    if np.any(np.abs(zeros) < 1e-9):
        raise DataError("the plant has a zero at s = 0; SIMC rules do not apply")
    lags = []
    for p in poles:
        if abs(p.imag) > 1e-12:
            if p.imag > 0:
                lags += [1.0 / abs(p)] * 2
        else:
            lags.append(-1.0 / p.real)
    theta = float(delay_s)
    lhp = []
    for z in zeros:
        if abs(z.imag) > 1e-12:
            raise DataError("complex plant zeros are not covered by the half rule")
        if z.real > 0:
            theta += 1.0 / z.real
        else:
            lhp.append(-1.0 / z.real)
    lags.sort(reverse=True)
    for T0 in sorted(lhp, reverse=True):
        bigger = [t for t in lags if t >= T0]
        tau0 = min(bigger) if bigger else (max(lags) if lags else None)
        if tau0 is None:
            raise DataError("an LHP zero without a lag to cancel: the plant is improper for SIMC")
        lags.remove(tau0)
        k *= _zero_factor(T0, tau0, theta)
    # lags kept in the reduced model: SIMC's double-integrating rule has none (all go to the delay)
    keep = {0: 2 if second_order else 1, 1: 1 if second_order else 0, 2: 0}[n_int]
    kept, rest = lags[:keep], lags[keep:]
    if rest:
        theta += rest[0] / 2.0 + sum(rest[1:])
        if kept:
            kept[-1] += rest[0] / 2.0
        else:
            theta += rest[0] / 2.0
    kept += [0.0] * (2 - len(kept))
    return HalfRuleModel(k=k, tau1_s=kept[0], tau2_s=kept[1], theta_s=theta, n_int=n_int)


def simc_pid(G, tau_c: float | None = None, delay_s: float = 0.0, controller: str = "pid",
             tf_ratio: float = 0.1) -> LoopGains:
    """SIMC PI/PID gains for ``G e^{-delay_s s}`` (parallel form, :class:`rotorlab.gains.LoopGains`).

    Rules (Skogestad 2003, table 4), with ``tau_c`` the desired closed-loop time constant (default
    ``theta``, "tight control"):

    * FOPTD ``k e^{-theta s}/(tau1 s + 1)``: ``kc = tau1/(k (tau_c + theta))``, ``tau_I = min(tau1, 4 (tau_c + theta))``;
      SOPTD adds ``tau_D = tau2``.
    * integrating ``k' e^{-theta s}/s`` (times ``1/(tau2 s+1)`` for PID): ``kc = 1/(k' (tau_c + theta))``,
      ``tau_I = 4 (tau_c + theta)``, ``tau_D = tau2``.
    * double integrating ``k'' e^{-theta s}/s^2``: ``kc = 1/(4 k'' (tau_c + theta)^2)``,
      ``tau_I = tau_D = 4 (tau_c + theta)`` (PID only).

    Parameters
    ----------
    G : continuous SISO plant without delay; delay_s : its delay (s).
    tau_c : closed-loop time constant, s. controller : 'pi' or 'pid'.
    tf_ratio : derivative filter time constant as a fraction of ``tau_D`` (``tf = tf_ratio tau_D``).

    Returns
    -------
    LoopGains
        Parallel-form gains ``kp``, ``ki = kp / tau_I``, ``kd = kp tau_D`` and the derivative filter ``tf``.

    Examples
    --------
    First-order plus delay, ``2 e^{-0.1 s} / (s + 1)``, ``tau_c = theta`` ("tight control"):

    >>> import control as ct
    >>> from rotorlab import tune
    >>> g = tune.simc_pid(ct.tf([2.0], [1, 1]), delay_s=0.1, controller="pi")
    >>> round(float(g.kp), 3), round(float(g.ki), 3)   # kc = tau1 / (k 2 theta) = 2.5, ki = kc / min(tau1, 8 theta)
    (2.5, 3.125)
    """
    if controller not in ("pi", "pid"):
        raise DataError(f"controller must be 'pi' or 'pid'; got {controller!r}")
    m = half_rule(G, delay_s, second_order=controller == "pid")
    tc = m.theta_s if tau_c is None else float(tau_c)
    if not tc > 0 and m.theta_s == 0:
        raise DataError("tau_c must be positive (the plant has no delay, so the default tau_c = theta is 0)")
    if tc < 0:
        raise DataError(f"tau_c must be non-negative; got {tc}")
    if m.n_int == 2:
        if controller == "pi":
            raise DataError("a double-integrating plant needs derivative action: use controller='pid'")
        kc = 1.0 / (4.0 * m.k * (tc + m.theta_s) ** 2)
        ti = td = 4.0 * (tc + m.theta_s)
    elif m.n_int == 1:
        kc = 1.0 / (m.k * (tc + m.theta_s))
        ti, td = 4.0 * (tc + m.theta_s), m.tau1_s if controller == "pid" else 0.0
    else:
        kc = m.tau1_s / (m.k * (tc + m.theta_s))
        ti, td = min(m.tau1_s, 4.0 * (tc + m.theta_s)), m.tau2_s
    kp = kc * (1.0 + td / ti)
    return LoopGains(kp=kp, ki=kc / ti, kd=kc * td, tf=tf_ratio * td if td else 0.0)
