"""Vinnicombe nu-gap metric and the generalized stability margin ``b_{P,C}``.

``nugap(G1, G2)`` is ``sup_w kappa(G1(jw), G2(jw))`` (chordal distance, largest singular value of
``(I + G2 G2*)^-1/2 (G2 - G1) (I + G1* G1)^-1/2``) when the winding-number condition holds, else 1.

The winding condition ``det(I + G2* G1) != 0`` on the boundary and
``wno det(I + G2~ G1) + eta(G1) - eta(G2) - eta0(G2) = 0`` is evaluated exactly by counting the unstable
zeros and poles of a state-space realisation of ``det(I + G2~ G1)`` (argument principle) instead of
tracking a phase along a frequency grid, which can miss fast phase turns. Discrete models are mapped to
continuous time by the bilinear transform ``z = (1 + s) / (1 - s)``, which maps the unit circle onto the
imaginary axis and leaves the chordal distances unchanged point by point, so one implementation serves both.
"""

from __future__ import annotations

import control as ct
import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize_scalar
from scipy.signal import ss2tf

from rotorlab.lti import as_ss, hinfnorm, is_discrete

__all__ = ["nugap", "chordal_distance", "stability_margin_bpc"]


def _abcd(sys):
    s = as_ss(sys)
    return tuple(np.asarray(M, dtype=float).reshape(shape) for M, shape in (
        (s.A, (s.nstates, s.nstates)), (s.B, (s.nstates, s.ninputs)),
        (s.C, (s.noutputs, s.nstates)), (s.D, (s.noutputs, s.ninputs))))


def _bilinear_to_s(A, B, C, D):
    """Realisation of ``G((1 + s) / (1 - s))`` (unit circle -> imaginary axis, ``w_s = tan(w dt / 2)``).

    Requires no pole at ``z = -1``.
    """
    n = A.shape[0]
    if n == 0:
        return A, B, C, D
    M = np.eye(n) + A
    Mi = np.linalg.inv(M)
    Ac = (A - np.eye(n)) @ Mi
    Bc = np.sqrt(2.0) * Mi @ B
    Cc = np.sqrt(2.0) * C @ Mi
    Dc = D - C @ Mi @ B
    return Ac, Bc, Cc, Dc


def _count(ev, tol):
    """(open right half-plane count, imaginary-axis count) of ``ev`` with a relative axis tolerance."""
    re = ev.real
    on = np.abs(re) <= tol * np.maximum(1.0, np.abs(ev))
    return int(np.sum((re > 0) & ~on)), int(np.sum(on))


def _winding_ok(A1, B1, C1, D1, A2, B2, C2, D2, tol=1e-9) -> bool:
    """Vinnicombe's winding-number condition for continuous-time realisations (argument principle)."""
    n1, n2 = A1.shape[0], A2.shape[0]
    # G2~(s) = G2(-s)^T = (-A2^T, C2^T, -B2^T, D2^T); F = I + G2~ G1, state [x1; x2].
    A = np.block([[A1, np.zeros((n1, n2))], [C2.T @ C1, -A2.T]])
    B = np.vstack([B1, C2.T @ D1])
    C = np.hstack([D2.T @ C1, -B2.T])
    Df = np.eye(D1.shape[1]) + D2.T @ D1
    if abs(np.linalg.det(Df)) < 1e-12:
        return False  # det(I + G2* G1) = 0 at infinite frequency
    zeros = np.linalg.eigvals(A - B @ np.linalg.solve(Df, C)) if A.size else np.zeros(0)
    poles = np.linalg.eigvals(A) if A.size else np.zeros(0)
    z_rhp, z_axis = _count(zeros, tol)
    if z_axis:
        return False  # det(I + G2* G1) vanishes on the boundary
    p_rhp, _ = _count(poles, tol)
    eta1, _ = _count(np.linalg.eigvals(A1), tol) if n1 else (0, 0)
    eta2, eta02 = _count(np.linalg.eigvals(A2), tol) if n2 else (0, 0)
    # Modes cancelled in F appear among both its poles and zeros, so Z - P is realisation-independent.
    return (z_rhp - p_rhp) + eta1 - eta2 - eta02 == 0


def chordal_distance(G1, G2, omega_rad_s) -> np.ndarray:
    """Pointwise chordal distance ``kappa(G1(jw), G2(jw))`` on ``omega_rad_s`` (rad/s).

    Parameters
    ----------
    G1, G2 : StateSpace or TransferFunction
        SISO models in the same time domain.
    omega_rad_s : array_like
        Frequencies, rad/s.

    Returns
    -------
    ndarray
        Distance in [0, 1] at each frequency (its maximum is at least the nu-gap where the winding condition holds).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> testbed = ct.tf([12.517, 36.374402], [1, 5.583, 21.3])
    >>> flight = ct.tf([13.8194, 38.1553634], [1, 5.198, 25.04])
    >>> print(np.round(ident.chordal_distance(testbed, flight, [1.0, 5.0, 20.0]), 3))
    [0.054 0.072 0.052]
    """
    d1, d2 = is_discrete(as_ss(G1)), is_discrete(as_ss(G2))
    if d1 != d2:
        raise ValueError("nugap: both models must be continuous or both discrete")
    s1, s2 = _abcd(G1), _abcd(G2)
    w = np.atleast_1d(np.asarray(omega_rad_s, dtype=float))
    pts = np.exp(1j * w * float(as_ss(G1).dt)) if d1 else 1j * w
    return _kappa(s1, s2, pts)


def _frf(A, B, C, D, pts):
    """Vectorised frequency response at complex points, (k, p, m): one batched solve, no Python loop."""
    n = A.shape[0]
    if n == 0:
        return np.broadcast_to(D, (len(pts),) + D.shape).astype(complex)
    # a grid point exactly on a boundary pole (an integrator at w = 0) is nudged off it
    pts = np.where(np.abs(pts) < 1e-12, 1e-9 + 0j, pts)
    M = pts[:, None, None] * np.eye(n) - A
    return C @ np.linalg.solve(M, np.broadcast_to(B, (len(pts),) + B.shape)) + D


def _kappa(s1, s2, pts):
    if s1[3].shape != s2[3].shape:
        raise ValueError(f"nugap: models have different sizes {s1[3].shape} and {s2[3].shape}")
    if s1[3].shape == (1, 1):
        return _kappa_siso(_tf(*s1), _tf(*s2), pts)
    G1 = _frf(*s1, pts)
    G2 = _frf(*s2, pts)
    out = np.empty(len(pts))
    for k in range(len(pts)):
        out[k] = _kappa_mimo(G1[k], G2[k])
    return out


def _tf(A, B, C, D):
    if A.shape[0] == 0:
        return np.atleast_1d(D[0, 0]), np.ones(1)
    num, den = ss2tf(A, B, C, D)
    return num[0], den


def _kappa_siso(tf1, tf2, pts):
    """SISO chordal distance from numerators and denominators: finite at poles on the boundary too."""
    n1, d1 = (np.polyval(c, pts) for c in tf1)
    n2, d2 = (np.polyval(c, pts) for c in tf2)
    num = np.abs(n1 * d2 - n2 * d1)
    den = np.sqrt((np.abs(n1) ** 2 + np.abs(d1) ** 2) * (np.abs(n2) ** 2 + np.abs(d2) ** 2))
    return num / den


def _kappa_mimo(g1, g2):
    p, m = g1.shape
    L = sla.sqrtm(np.eye(p) + g2 @ g2.conj().T)
    R = sla.sqrtm(np.eye(m) + g1.conj().T @ g1)
    X = np.linalg.solve(L, g2 - g1) @ np.linalg.inv(R)
    return float(np.linalg.norm(X, 2))


def nugap(G1, G2, n_grid: int = 400, refine: bool = True) -> float:
    """Vinnicombe nu-gap between two LTI models (continuous, or discrete with the same ``dt``).

    Parameters
    ----------
    G1, G2 : StateSpace or TransferFunction (or IdentifiedModel: its delay-free ``sys`` is used)
        Same input/output sizes.
    n_grid : int
        Log-spaced frequency points covering the poles and zeros (plus 0 and infinity / Nyquist).
    refine : bool
        Polish the grid maximum with a bounded scalar search (the sup is what matters).

    Returns
    -------
    float in [0, 1]; 1 when the winding-number condition fails.

    Examples
    --------
    The two published P2-A2 pitch models, test-bed and in flight (the paper prints 0.0741 from unrounded models):

    >>> import control as ct
    >>> from rotorlab import ident
    >>> testbed = ct.tf([12.517, 36.374402], [1, 5.583, 21.3])
    >>> flight = ct.tf([13.8194, 38.1553634], [1, 5.198, 25.04])
    >>> print(round(ident.nugap(testbed, flight), 4))
    0.0735
    """
    G1 = getattr(G1, "sys", G1)
    G2 = getattr(G2, "sys", G2)
    S1, S2 = as_ss(G1), as_ss(G2)
    d1, d2 = is_discrete(S1), is_discrete(S2)
    if d1 != d2:
        raise ValueError("nugap: both models must be continuous or both discrete")
    if d1 and not np.isclose(float(S1.dt), float(S2.dt)):
        raise ValueError(f"nugap: sample times differ ({S1.dt} vs {S2.dt} s)")
    if (S1.noutputs, S1.ninputs) != (S2.noutputs, S2.ninputs):
        raise ValueError(f"nugap: models have different sizes {(S1.noutputs, S1.ninputs)} and {(S2.noutputs, S2.ninputs)}")
    s1, s2 = _abcd(S1), _abcd(S2)
    if d1:
        c1, c2 = _bilinear_to_s(*s1), _bilinear_to_s(*s2)
    else:
        c1, c2 = s1, s2
    if not _winding_ok(*c1, *c2):
        return 1.0
    # Work on the (bilinear-mapped) continuous models: a log grid spanning all pole/zero magnitudes.
    ev = np.concatenate([np.linalg.eigvals(c[0]) for c in (c1, c2) if c[0].size] or [np.ones(1)])
    mags = np.abs(ev[np.abs(ev) > 1e-12]) if np.any(np.abs(ev) > 1e-12) else np.ones(1)
    lo, hi = np.log10(mags.min()) - 2, np.log10(mags.max()) + 2
    w = np.concatenate([[0.0], np.logspace(lo, hi, n_grid)])
    if c1[3].shape == (1, 1):
        tf1, tf2 = _tf(*c1), _tf(*c2)
        kap = lambda pts: _kappa_siso(tf1, tf2, pts)
        k_inf = _kappa_siso((c1[3][0], np.ones(1)), (c2[3][0], np.ones(1)), np.zeros(1))[0]
    else:
        kap = lambda pts: _kappa(c1, c2, pts)
        k_inf = _kappa_mimo(c1[3], c2[3])
    k = kap(1j * w)  # at infinite frequency (discrete: Nyquist) kappa is that of the feedthroughs, k_inf
    i = int(np.argmax(k))
    best = max(k[i], k_inf)
    if refine and k[i] >= k_inf and 0 < i < len(w) - 1:
        res = minimize_scalar(lambda lw: -kap(np.array([1j * 10 ** lw]))[0],
                              bounds=(np.log10(w[i - 1]) if w[i - 1] > 0 else lo - 1, np.log10(w[i + 1])),
                              method="bounded",
                              options={"xatol": 1e-5})
        best = max(best, -res.fun)
    return float(min(best, 1.0))


def stability_margin_bpc(P, C) -> float:
    """Generalized stability margin ``b_{P,C} = 1 / || [P; I] (I + C P)^-1 [C, I] ||_inf`` (negative feedback).

    0 when the loop is not internally stable. Robust-stability link: the loop stays stable for every plant
    within nu-gap ``< b_{P,C}`` of ``P`` (Vinnicombe).

    Parameters
    ----------
    P, C : StateSpace or TransferFunction
        Plant and controller, in the same time domain.

    Returns
    -------
    float
        ``b_{P,C}`` in [0, 1].

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> P, C = ct.tf([1.0], [1, 1]), ct.tf([1.0], [1])
    >>> round(ident.stability_margin_bpc(P, C), 4)            # 1/sqrt(2) for P = 1/(s + 1), C = 1
    0.7071
    """
    P, C = as_ss(P), as_ss(C)
    m = P.ninputs
    dt = P.dt
    Im = ct.ss([], [], [], np.eye(m), dt)
    S = ct.feedback(Im, ct.series(P, C))  # (I + C P)^-1 at the plant input
    left = ct.series(ct.ss([], [], [], np.vstack([np.eye(m), np.eye(m)]), dt), ct.append(P, Im))
    right = ct.series(ct.append(C, Im), ct.ss([], [], [], np.hstack([np.eye(m), np.eye(m)]), dt))
    H = ct.series(right, S, left)
    gamma, _ = hinfnorm(H)
    return 0.0 if not np.isfinite(gamma) else float(1.0 / gamma)
