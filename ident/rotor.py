"""Rotor and motor fits from thrust-stand logs (doc 000 "thrust-stand tests", doc 002 sec. 2.2-2.3).

Static: thrust and torque coefficients from ``T = K_T Omega^2`` / ``Q = K_Q Omega^2`` (and the
non-dimensional ``C_T``, ``C_Q = C_P`` in the TUHH convention ``T = C_T rho A R^2 Omega^2``,
``Q = C_Q rho A R^3 Omega^2``, ``A = pi R^2``), command-to-speed maps (linear, quadratic, power law
``Omega = a0 b^a1 + a2``) and thrust linear in blade pitch for variable-pitch rotors.
Dynamic: first-order gain, time constant and delay of the motor from command steps, fitted by output error
(:func:`rotorlab.ident.greybox.oe_fit` on :func:`rotorlab.ident.structures.first_order_structure`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize as opt

from rotorlab.errors import DataError
from rotorlab.ident.greybox import oe_fit
from rotorlab.ident.structures import first_order_structure

__all__ = [
    "CoefficientFit",
    "SpeedMapFit",
    "LinearFit",
    "FirstOrderFit",
    "fit_thrust_coefficient",
    "fit_torque_coefficient",
    "fit_speed_map",
    "fit_pitch_thrust",
    "fit_first_order_steps",
]


def _vec(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).ravel()
    if a.size < 3:
        raise DataError(f"{name}: need at least 3 samples for a fit, got {a.size}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"{name}: non-finite value at index {int(np.flatnonzero(~np.isfinite(a))[0])}")
    return a


def _same_len(*pairs):
    n = {len(a) for _, a in pairs}
    if len(n) != 1:
        raise DataError("signals differ in length: " + ", ".join(f"{k}={len(a)}" for k, a in pairs))


@dataclass
class CoefficientFit:
    """``value = K Omega^2`` fit through the origin.

    Attributes
    ----------
    K : float
        ``N s^2`` for thrust, ``N m s^2`` for torque (per ``rad^2``).
    K_std : float
        Standard error of ``K``.
    coefficient : float or None
        Non-dimensional ``C_T`` or ``C_Q`` (= ``C_P``), when ``rho`` and ``radius_m`` were given.
    coefficient_std : float or None
    r2 : float
        Coefficient of determination.
    rmse : float
    """

    K: float
    K_std: float
    coefficient: float | None
    coefficient_std: float | None
    r2: float
    rmse: float

    def predict(self, omega_rad_s) -> np.ndarray:
        return self.K * np.asarray(omega_rad_s, dtype=float) ** 2


def _fit_square(omega, value, denom):
    x = omega**2
    K = float(x @ value / (x @ x))
    r = value - K * x
    dof = max(len(x) - 1, 1)
    s2 = float(r @ r) / dof
    K_std = math.sqrt(s2 / float(x @ x))
    ss = float(((value - value.mean()) ** 2).sum())
    r2 = 1.0 - float(r @ r) / ss if ss > 0 else float("nan")
    coef = None if denom is None else K / denom
    coef_std = None if denom is None else K_std / denom
    return CoefficientFit(K, K_std, coef, coef_std, r2, math.sqrt(float(r @ r) / len(x)))


def fit_thrust_coefficient(omega_rad_s, thrust_N, rho: float | None = None,
                           radius_m: float | None = None) -> CoefficientFit:
    """Thrust coefficient from a thrust-stand sweep: ``T = K_T Omega^2``; ``C_T = K_T / (rho pi R^4)``.

    Parameters
    ----------
    omega_rad_s : array_like
        Rotor speed (rad/s).
    thrust_N : array_like
        Thrust (N).
    rho : float, optional
        Air density (kg/m^3); with ``radius_m`` gives ``C_T``.
    radius_m : float, optional
        Rotor radius (m).
    """
    w, T = _vec(omega_rad_s, "omega_rad_s"), _vec(thrust_N, "thrust_N")
    _same_len(("omega_rad_s", w), ("thrust_N", T))
    denom = None if rho is None or radius_m is None else rho * math.pi * radius_m**4
    return _fit_square(w, T, denom)


def fit_torque_coefficient(omega_rad_s, torque_Nm=None, power_W=None, rho: float | None = None,
                           radius_m: float | None = None) -> CoefficientFit:
    """Torque coefficient ``Q = K_Q Omega^2`` from torque, or from shaft power (``Q = P / Omega``);
    ``C_Q = C_P = K_Q / (rho pi R^5)``."""
    w = _vec(omega_rad_s, "omega_rad_s")
    if (torque_Nm is None) == (power_W is None):
        raise ValueError("give exactly one of torque_Nm and power_W")
    if torque_Nm is not None:
        Q = _vec(torque_Nm, "torque_Nm")
        _same_len(("omega_rad_s", w), ("torque_Nm", Q))
    else:
        P = _vec(power_W, "power_W")
        _same_len(("omega_rad_s", w), ("power_W", P))
        if np.any(w <= 0):
            raise DataError("power_W: torque from power needs omega_rad_s > 0 at every sample; "
                            f"first bad index {int(np.flatnonzero(w <= 0)[0])}")
        Q = P / w
    denom = None if rho is None or radius_m is None else rho * math.pi * radius_m**5
    return _fit_square(w, Q, denom)


@dataclass
class SpeedMapFit:
    """Command-to-speed map ``Omega(b)``.

    Attributes
    ----------
    kind : {'linear', 'quadratic', 'power'}
        ``c0 + c1 b``, ``c0 + c1 b + c2 b^2``, or ``a0 b^a1 + a2``.
    coeffs : dict[str, float]
        ``c0, c1[, c2]`` or ``a0, a1, a2`` (speed unit of the data, 1/s for rad/s).
    std : dict[str, float]
        Standard errors.
    cov : ndarray
    rmse : float
    """

    kind: str
    coeffs: dict
    std: dict
    cov: np.ndarray
    rmse: float

    def predict(self, b) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        c = self.coeffs
        if self.kind == "power":
            return c["a0"] * b ** c["a1"] + c["a2"]
        return c["c0"] + c["c1"] * b + (c.get("c2", 0.0) * b**2)

    def slope(self, b) -> np.ndarray:
        """``dOmega/db`` (the linearised motor gain, e.g. TUHH's Gamma at hover)."""
        b = np.asarray(b, dtype=float)
        c = self.coeffs
        if self.kind == "power":
            return c["a0"] * c["a1"] * b ** (c["a1"] - 1.0)
        return c["c1"] + 2.0 * c.get("c2", 0.0) * b


def fit_speed_map(command, omega, kind: str = "power", p0=None) -> SpeedMapFit:
    """Fit the motor command ``b`` to speed ``Omega`` map (doc 002 eq. 3 for ``kind='power'``).

    Linear and quadratic maps are linear least squares; the power law ``a0 b^a1 + a2`` uses
    ``scipy.optimize.curve_fit``, started from a log-log fit unless ``p0`` is given. ``command`` must be
    positive for the power law.
    """
    b, w = _vec(command, "command"), _vec(omega, "omega")
    _same_len(("command", b), ("omega", w))
    if kind in ("linear", "quadratic"):
        deg = 1 if kind == "linear" else 2
        X = np.vander(b, deg + 1, increasing=True)
        coef, *_ = np.linalg.lstsq(X, w, rcond=None)
        r = w - X @ coef
        s2 = float(r @ r) / max(len(b) - deg - 1, 1)
        cov = s2 * np.linalg.inv(X.T @ X)
        names = ["c0", "c1", "c2"][: deg + 1]
    elif kind == "power":
        if np.any(b <= 0):
            raise DataError(f"command: the power law needs b > 0; first bad index {int(np.flatnonzero(b <= 0)[0])}")
        if p0 is None:
            # power law through the origin on log axes, offset zero: close enough for curve_fit to converge
            ok = w > 0
            a1, la0 = np.polyfit(np.log(b[ok]), np.log(w[ok]), 1)
            p0 = (math.exp(la0), a1, 0.0)
        coef, cov = opt.curve_fit(lambda x, a0, a1, a2: a0 * x**a1 + a2, b, w, p0=p0, maxfev=20000)
        r = w - (coef[0] * b ** coef[1] + coef[2])
        names = ["a0", "a1", "a2"]
    else:
        raise ValueError(f"kind must be 'linear', 'quadratic' or 'power', got {kind!r}")
    std = np.sqrt(np.diag(cov))
    return SpeedMapFit(kind, dict(zip(names, map(float, coef))), dict(zip(names, map(float, std))), cov,
                       float(np.sqrt(np.mean(r**2))))


@dataclass
class LinearFit:
    """``y = intercept + slope x`` with standard errors."""

    intercept: float
    slope: float
    intercept_std: float
    slope_std: float
    rmse: float

    def predict(self, x) -> np.ndarray:
        return self.intercept + self.slope * np.asarray(x, dtype=float)


def fit_pitch_thrust(pitch_rad, thrust_N) -> LinearFit:
    """Variable-pitch rotor at fixed speed: thrust linear in collective blade pitch,
    ``T = T0 + T_theta theta`` (the control derivative behind doc 000's ``dM/du``)."""
    x, y = _vec(pitch_rad, "pitch_rad"), _vec(thrust_N, "thrust_N")
    _same_len(("pitch_rad", x), ("thrust_N", y))
    X = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ coef
    cov = float(r @ r) / max(len(x) - 2, 1) * np.linalg.inv(X.T @ X)
    sd = np.sqrt(np.diag(cov))
    return LinearFit(float(coef[0]), float(coef[1]), float(sd[0]), float(sd[1]), float(np.sqrt(np.mean(r**2))))


@dataclass
class FirstOrderFit:
    """Motor dynamics ``Omega/b = K e^(-s delay_s)/(tau s + 1)`` around the initial operating point.

    Attributes
    ----------
    gain, tau_s, delay_s : float
    ci95 : dict[str, tuple[float, float]]
    greybox : GreyBoxResult
        The full output-error result (covariance, VAF, ...).
    """

    gain: float
    tau_s: float
    delay_s: float
    ci95: dict
    greybox: object

    @property
    def pole_rad_s(self) -> float:
        """Motor pole magnitude ``1/tau`` (TUHH's ``|p|``)."""
        return 1.0 / self.tau_s


def fit_first_order_steps(command, output, dt: float, delay: bool = True, tau0_s: float | None = None,
                          rng=None) -> FirstOrderFit:
    """First-order (plus optional delay) motor model from command steps sampled at ``dt``.

    The record must start at steady state: deviations from the first sample are fitted (gain and lag
    are those of the linearisation at that operating point).
    """
    u, y = _vec(command, "command"), _vec(output, "output")
    _same_len(("command", u), ("output", y))
    du, dy = u - u[0], y - y[0]
    if np.ptp(du) == 0:
        raise DataError("command: constant; the steps needed to see the motor dynamics are missing")
    K0 = float(np.linalg.lstsq(du[:, None], dy, rcond=None)[0][0])
    tau0 = tau0_s if tau0_s is not None else 10 * dt
    model = first_order_structure(K=K0, tau=tau0, delay_s=2 * dt if delay else 0.0,
                                  fixed=() if delay else ("delay_s",))
    res = oe_fit(model, du, dy, dt, restarts=2, rng=rng)
    return FirstOrderFit(res.params["K"], res.params["tau"], res.params["delay_s"], res.ci95, res)
