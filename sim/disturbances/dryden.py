"""Dryden continuous turbulence, low-altitude model of MIL-F-8785C / MIL-HDBK-1797 (h < 1000 ft).

Velocity components along the mean wind (``u``), lateral (``v``) and vertical (``w``), in m/s. Scales (the
standard is written in feet; converted here), with the altitude floored at 10 ft as the standard's plots are:

    L_w = h,   L_u = L_v = h / (0.177 + 0.000823 h)^1.2                       [ft]
    sigma_w = 0.1 W20,   sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4

with ``W20`` the mean wind at 20 ft (6.1 m). One-sided PSDs over temporal frequency ``omega`` (rad/s) with the
airspeed ``V`` (Taylor's frozen turbulence; for a hovering vehicle ``V`` is the mean wind), each integrating to
``sigma^2`` over ``omega`` in [0, inf):

    Phi_u(omega) = sigma_u^2 (2 L_u / (pi V)) / (1 + (L_u omega / V)^2)
    Phi_v(omega) = sigma_v^2 (L_v / (pi V)) (1 + 3 (L_v omega / V)^2) / (1 + (L_v omega / V)^2)^2   (same for w)

Shaping filters driven by unit-intensity continuous white noise:

    H_u(s) = sigma_u sqrt(2 L_u / V) / (1 + (L_u / V) s)
    H_v(s) = sigma_v sqrt(L_v / V) (1 + sqrt(3) (L_v / V) s) / (1 + (L_v / V) s)^2

Discretisation is exact for white-noise input (not a zero-order hold of a sampled noise): the state transition
``expm(A dt)`` and the process-noise covariance ``Qd = int_0^dt e^{A s} B B' e^{A' s} ds`` (Van Loan's matrix
exponential), so the sampled sequence has exactly the covariance of the continuous process at the sample times
(variance ``sigma^2``, PSD the aliased continuous one). Each realisation is generated with
``scipy.signal.lfilter`` on independent Gaussian channels, after a burn-in so it starts stationary.

Gust gradients (MIL-F-8785C 3.7.3.2; Madden, "Verifying implementation of the Dryden turbulence model and
MIL-F-8785 gust gradient", NASA Langley): the turbulence's rotation over a span ``b``, the air-relative
rotational rates ``p_g, q_g, r_g`` (rad/s) an aircraft flies in besides the gust velocities,

    Phi_p(omega) = sigma_w^2 / (V L_w) 0.8 (pi L_w / (4 b))^(1/3) / (1 + (4 b omega / (pi V))^2)
    Phi_q(omega) = (omega / V)^2 / (1 + (4 b omega / (pi V))^2) Phi_w(omega)
    Phi_r(omega) = (omega / V)^2 / (1 + (3 b omega / (pi V))^2) Phi_v(omega)

The rotation about ``v`` and ``w`` comes from the ``w`` and ``v`` records (filters ``(s / V) / (1 + (4 b / (pi V))
s)`` and ``-(s / V) / (1 + (3 b / (pi V)) s)``: the frozen field's rigid rotation, Tustin at the record's sample time,
their corners far below its Nyquist frequency); about ``u`` it is its own first-order process, discretised exactly
like the velocities.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla
from scipy import signal

from rotorlab.errors import ConfigError

FT = 0.3048


def low_altitude_scales(altitude_m: float, wind20_mps: float):
    """MIL-F-8785C low-altitude scales: ``(sigma_uvw (3,) m/s, L_uvw (3,) m)``."""
    h = max(altitude_m / FT, 10.0)
    if h > 1000.0:
        raise ConfigError("the low-altitude Dryden model holds below 1000 ft", field="altitude_m",
                          expected="<= 304.8 m", got=altitude_m)
    k = 0.177 + 0.000823 * h
    L_uv = h / k ** 1.2 * FT
    sw = 0.1 * wind20_mps
    suv = sw / k ** 0.4
    return np.array([suv, suv, sw]), np.array([L_uv, L_uv, h * FT])


def dryden_psd_u(omega, sigma, L, V):
    """Longitudinal one-sided PSD, (m/s)^2 per rad/s, at ``omega`` rad/s."""
    x = L * np.asarray(omega, dtype=float) / V
    return sigma ** 2 * 2.0 * L / (math.pi * V) / (1.0 + x * x)


def dryden_psd_v(omega, sigma, L, V):
    """Lateral (and vertical, with ``L_w``/``sigma_w``) one-sided PSD, (m/s)^2 per rad/s."""
    x = L * np.asarray(omega, dtype=float) / V
    return sigma ** 2 * L / (math.pi * V) * (1.0 + 3.0 * x * x) / (1.0 + x * x) ** 2


dryden_psd_w = dryden_psd_v


def dryden_psd_rates(omega, sigma_uvw, L_uvw, V, span_m):
    """One-sided PSDs of the gust gradients ``(p_g, q_g, r_g)``, (rad/s)^2 per rad/s, shape ``(len(omega), 3)``
    (MIL-F-8785C; ``span_m`` the span the gradient is taken over)."""
    w = np.asarray(omega, dtype=float)
    sw, Lw, b = float(sigma_uvw[2]), float(L_uvw[2]), float(span_m)
    p = sw ** 2 / (V * Lw) * 0.8 * (math.pi * Lw / (4.0 * b)) ** (1.0 / 3.0) / (1.0 + (4.0 * b * w / (math.pi * V)) ** 2)
    q = (w / V) ** 2 / (1.0 + (4.0 * b * w / (math.pi * V)) ** 2) * dryden_psd_w(w, sw, Lw, V)
    r = (w / V) ** 2 / (1.0 + (3.0 * b * w / (math.pi * V)) ** 2) * dryden_psd_v(w, sigma_uvw[1], L_uvw[1], V)
    return np.column_stack([p, q, r])


def _filter_ss(kind: str, sigma: float, L: float, V: float):
    T = L / V
    if kind == "u":
        return (np.array([[-1.0 / T]]), np.array([[1.0]]), np.array([[sigma * math.sqrt(2.0 * L / V) / T]]))
    # controllable canonical form of g (1 + sqrt3 T s) / (T s + 1)^2 = g/T^2 (sqrt3 T s + 1) / (s^2 + 2/T s + 1/T^2)
    g = sigma * math.sqrt(L / V) / T ** 2
    A = np.array([[0.0, 1.0], [-1.0 / T ** 2, -2.0 / T]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[g, g * math.sqrt(3.0) * T]])
    return A, B, C


def exact_noise_discretisation(A, B, dt: float):
    """``(Ad, Qd)`` of ``dx = A x dt + B dW`` (unit-intensity white noise) sampled every ``dt``: Van Loan (1978)."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = B @ B.T
    M[n:, n:] = A.T
    E = sla.expm(M * dt)
    Ad = E[n:, n:].T
    Qd = Ad @ E[:n, n:]
    return Ad, 0.5 * (Qd + Qd.T)


#: the Dryden spectra model subsonic low-altitude flight; far above, the shaping filters' covariance overflowed
MAX_AIRSPEED_MPS = 340.0


class DrydenTurbulence:
    """Seeded Dryden gust-velocity generator.

    Parameters
    ----------
    V_mps : float
        Speed of the vehicle relative to the air mass (> 0; for hover, the mean wind speed).
    altitude_m : float
        Height above ground, m (the scales use it, floored at 10 ft).
    sigma_mps : float or (3,), optional
        Turbulence intensities (u, v, w), m/s; a scalar applies to all three. Default from ``wind20_mps``.
    wind20_mps : float, optional
        Mean wind at 20 ft, m/s, for the standard intensities; default ``V_mps``.
    length_scales_m : (3,), optional
        ``L_u, L_v, L_w`` in m; default from the altitude.
    seed, rng : int or numpy.random.Generator
    """

    def __init__(self, V_mps: float, altitude_m: float, sigma_mps=None, wind20_mps: float | None = None,
                 length_scales_m=None, seed=None, rng: np.random.Generator | None = None):
        if not 0 < V_mps <= MAX_AIRSPEED_MPS:
            raise ConfigError("Dryden turbulence is frozen turbulence advected at the airspeed", field="V_mps",
                              expected=f"a speed in (0, {MAX_AIRSPEED_MPS:g}] m/s (for hover: the mean wind)",
                              got=V_mps)
        sig_std, L_std = low_altitude_scales(altitude_m, V_mps if wind20_mps is None else wind20_mps)
        sigma = sig_std if sigma_mps is None else np.broadcast_to(np.asarray(sigma_mps, float), (3,)).copy()
        L = L_std if length_scales_m is None else np.asarray(length_scales_m, float).reshape(3)
        if np.any(sigma < 0) or np.any(L <= 0):
            raise ConfigError(field="sigma_mps/length_scales_m", expected="sigma >= 0 and L > 0",
                              got=(sigma.tolist(), L.tolist()))
        self.V_mps = float(V_mps)
        self.sigma_mps = sigma
        self.length_scales_m = L
        self.rng = rng if rng is not None else np.random.default_rng(seed)

    def psd(self, omega):
        """One-sided PSDs of (u, v, w), shape ``(len(omega), 3)``, (m/s)^2 per rad/s."""
        s, L, V = self.sigma_mps, self.length_scales_m, self.V_mps
        return np.column_stack([dryden_psd_u(omega, s[0], L[0], V), dryden_psd_v(omega, s[1], L[1], V),
                                dryden_psd_w(omega, s[2], L[2], V)])

    def generate(self, n: int, dt: float) -> np.ndarray:
        """``n`` samples every ``dt`` s of (u, v, w) gust velocity, m/s, shape ``(n, 3)``."""
        return np.column_stack([y[k:] for y, k in self._velocities(n, dt)])

    def _velocities(self, n: int, dt: float):
        """Per component (u, v, w): the record with its burn-in in front, and the burn-in's length (samples)."""
        n = int(n)
        if n < 1 or not dt > 0:
            raise ConfigError(field="n/dt", expected="n >= 1 and dt > 0", got=(n, dt))
        out = []
        for j, kind in enumerate("uvw"):
            A, B, C = _filter_ss("u" if kind == "u" else "v", self.sigma_mps[j], self.length_scales_m[j], self.V_mps)
            Ad, Qd = exact_noise_discretisation(A, B, dt)
            G = sla.cholesky(Qd, lower=True)
            # burn-in of 10 time constants so the record starts from the stationary distribution
            n_burn = int(math.ceil(10.0 * self.length_scales_m[j] / self.V_mps / dt))
            e = self.rng.standard_normal((n + n_burn, G.shape[1]))
            y = np.zeros(n + n_burn)
            for c in range(G.shape[1]):
                # x_{k+1} = Ad x_k + G e_k, y_k = C x_k: each noise channel through C (zI - Ad)^-1 G[:, c]
                num, den = signal.ss2tf(Ad, G[:, [c]], C, np.zeros((1, 1)))
                y += signal.lfilter(num[0], den, e[:, c])
            out.append((y, n_burn))
        return out

    def psd_rates(self, omega, span_m: float):
        """One-sided PSDs of ``(p_g, q_g, r_g)`` over ``span_m``, (rad/s)^2 per rad/s, ``(len(omega), 3)``."""
        return dryden_psd_rates(omega, self.sigma_mps, self.length_scales_m, self.V_mps, span_m)

    def generate_with_rates(self, n: int, dt: float, span_m: float):
        """``(uvw, rot)``: :meth:`generate`'s gust velocities (m/s, ``(n, 3)``, the same record for the same
        seed) and the air's rotation that goes with them over the span ``span_m`` (rad/s, ``(n, 3)``, about the
        u, v, w axes), with the standard's gust-gradient spectra: about ``u`` its own process (``Phi_p``), about
        ``v`` and ``w`` the frozen field's rigid rotation ``-dw/dx = +(dw/dt) / V`` and ``dv/dx = -(dv/dt) / V``
        (air advected along ``+u``), each seen through the span's averaging filter (``Phi_q``, ``Phi_r``). Every
        component starts stationary: the gradients run over the velocities' burn-in, and the ``u`` rotation
        draws its noise after the velocities' draws."""
        if not span_m > 0:
            raise ConfigError(field="span_m", expected="the span the gust gradient is taken over, > 0 m", got=span_m)
        comps = self._velocities(n, dt)
        n, V, b = int(n), self.V_mps, float(span_m)
        rates = np.empty((n, 3))
        # about u: K / (1 + T s) with pi Phi_p(0) = K^2 (the module's unit-intensity noise convention, Phi = |H|^2 / pi)
        T = 4.0 * b / (math.pi * V)
        K = math.sqrt(math.pi * self.psd_rates([0.0], b)[0, 0])
        Ad, Qd = exact_noise_discretisation(np.array([[-1.0 / T]]), np.array([[1.0]]), dt)
        n_burn = int(math.ceil(10.0 * T / dt))
        e = self.rng.standard_normal(n + n_burn) * math.sqrt(Qd[0, 0])
        rates[:, 0] = (K / T) * signal.lfilter([0.0, 1.0], [1.0, -Ad[0, 0]], e)[n_burn:]
        for j, src, Tg, sign in ((1, 2, T, 1.0), (2, 1, 3.0 * b / (math.pi * V), -1.0)):
            y, k = comps[src]
            num, den, _ = signal.cont2discrete(([sign / V, 0.0], [Tg, 1.0]), dt, method="bilinear")
            # over the velocity's burn-in (>= 10 L/V, far longer than the gradient filter's Tg < 1 s)
            rates[:, j] = signal.lfilter(num.ravel(), den, y)[k:]
        return np.column_stack([y[k:] for y, k in comps]), rates
