"""On-line LMS estimation of an impulse response and Kung's (ERA) realisation of it.

The published flight software ran an LMS adaptive FIR filter on board and turned the estimated impulse
response into a state-space model with Kung's algorithm (000_*.txt, "LMS"; 001_*.txt).
"""

from __future__ import annotations

import control as ct
import numpy as np
import scipy.linalg as sla
from tqdm import tqdm

from rotorlab.errors import DataError

from ._data import check_int, check_io
from .model import IdentifiedModel

__all__ = ["LMS", "lms_batch", "kung"]


class LMS:
    """Adaptive FIR filter ``y_hat(k) = w^T [u(k), u(k-1), ..., u(k-L+1)]`` updated by (normalised) LMS.

    ``w <- (1 - mu * leakage) w + step * e * u_window`` with ``e = y - y_hat`` and ``step = mu`` (plain
    LMS, stable for ``0 < mu < 2 / (L * var(u))``) or ``mu / (eps + |u_window|^2)`` (normalised, stable for
    ``0 < mu < 2`` whatever the input scale).

    Built for a flight-software loop: every buffer is allocated once and :meth:`update` allocates nothing.

    Parameters
    ----------
    taps : int
        FIR length L (impulse-response samples estimated, ``w[0]`` is the direct term).
    mu : float
        Step size.
    normalized : bool
        Normalised LMS (default).
    leakage : float
        Leakage factor (>= 0); trades a small bias for robustness to poorly exciting input.
    eps : float
        Regulariser of the normalisation.
    """

    def __init__(self, taps: int, mu: float = 0.5, normalized: bool = True, leakage: float = 0.0, eps: float = 1e-8):
        self.taps = check_int(taps, "taps", 1)
        if not mu > 0:
            raise DataError(f"LMS step size mu must be positive; got {mu}")
        if leakage < 0:
            raise DataError(f"LMS leakage must be >= 0; got {leakage}")
        self.mu, self.normalized, self.leakage, self.eps = float(mu), bool(normalized), float(leakage), float(eps)
        self.w = np.zeros(self.taps)
        # Doubled ring buffer: the current window is always the contiguous view buf[pos:pos + L],
        # newest sample first, so no shifting or copying per step.
        self._buf = np.zeros(2 * self.taps)
        self._pos = 0
        self._tmp = np.zeros(self.taps)

    def reset(self) -> None:
        self.w[:] = 0.0
        self._buf[:] = 0.0
        self._pos = 0

    def update(self, u_k: float, y_k: float) -> float:
        """Feed one input/output sample; returns the a-priori prediction ``y_hat(k)`` (before the update)."""
        L = self.taps
        self._pos = (self._pos - 1) % L
        self._buf[self._pos] = u_k
        self._buf[self._pos + L] = u_k
        x = self._buf[self._pos: self._pos + L]
        y_hat = float(np.dot(self.w, x))
        e = y_k - y_hat
        step = self.mu / (self.eps + float(np.dot(x, x))) if self.normalized else self.mu
        if self.leakage:
            self.w *= 1.0 - self.mu * self.leakage
        np.multiply(x, step * e, out=self._tmp)
        self.w += self._tmp
        return y_hat

    @property
    def impulse_response(self) -> np.ndarray:
        """Copy of the current weights = impulse-response estimate ``h[0..L-1]``."""
        return self.w.copy()


def lms_batch(u, y, taps: int, mu: float = 0.5, normalized: bool = True, leakage: float = 0.0,
              delay: int = 0, progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Run :class:`LMS` over a SISO record.

    Parameters
    ----------
    u, y : array_like, shape (N,)
    taps, mu, normalized, leakage
        As for :class:`LMS`.
    delay : int
        Known input delay in samples, removed first (``u[k - delay]`` paired with ``y[k]``), so the taps
        are spent on the dynamics.

    Returns
    -------
    h : ndarray, shape (taps,)
        Final impulse-response estimate (of the delay-free system).
    y_hat : ndarray, shape (N - delay,)
        A-priori predictions along the record.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)

    >>> h, y_hat = ident.lms_batch(u, y, taps=60)
    >>> h_true = ct.impulse_response(G, T=np.arange(60) * 0.02).y[0, 0] * 0.02
    >>> bool(np.max(np.abs(h - h_true)) < 0.01 * np.max(np.abs(h_true)))  # the taps converge to the impulse response
    True
    """
    u2, y2 = check_io(u, y, min_samples=taps + 1 + delay, what=f"LMS with {taps} taps", sized_by="number of taps")
    if u2.shape[1] != 1 or y2.shape[1] != 1:
        raise DataError(f"lms_batch is SISO; got {u2.shape[1]} input(s) and {y2.shape[1]} output(s)")
    d = check_int(delay, "delay", 0)
    uu, yy = u2[: len(u2) - d, 0], y2[d:, 0]
    f = LMS(taps, mu, normalized, leakage)
    y_hat = np.empty(len(uu))
    it = range(len(uu))
    if progress:
        it = tqdm(it, desc="LMS")
    for k in it:
        y_hat[k] = f.update(uu[k], yy[k])
    return f.impulse_response, y_hat


def kung(h, order: int | None = None, dt: float = 1.0, energy: float = 0.99, threshold: float | None = None,
         delay: int = 0) -> IdentifiedModel:
    """Kung's realisation (ERA) of a state-space model from its Markov parameters.

    Parameters
    ----------
    h : array_like, shape (N,) or (N, p, m)
        Impulse response ``h[0] = D``, ``h[k] = C A^(k-1) B``.
    order : int, optional
        Model order; otherwise the smallest order whose Hankel singular values hold ``energy`` of the
        total squared sum, or that keeps every singular value above ``threshold`` times the largest.
    dt : float
        Sample time, s.
    delay : int
        Delay in samples to record in the result (``h`` is of the delay-free system).

    Returns
    -------
    IdentifiedModel
        ``method = "kung"``, ``singular_values`` the Hankel singular values.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)
    >>> h = ct.impulse_response(G, T=np.arange(60) * 0.02).y[0, 0] * 0.02  # Markov parameters h[k]
    >>> m = ident.kung(h, dt=0.02)              # order from the Hankel singular values
    >>> m.sys.nstates
    2
    """
    H = np.asarray(h, dtype=float)
    if H.ndim == 1:
        H = H[:, None, None]
    if H.ndim != 3:
        raise DataError(f"h must be (N,) or (N, p, m); got shape {H.shape}")
    if not np.all(np.isfinite(H)):
        raise DataError("h contains NaN/inf")
    N, p, m = H.shape
    r = (N - 1) // 2  # block rows = block columns of the Hankel matrix (uses h[1..2r])
    if r < 1:
        raise DataError(f"kung needs at least 3 impulse-response samples; got {N}")
    Hk = np.block([[H[1 + i + j] for j in range(r)] for i in range(r)])
    Hs = np.block([[H[2 + i + j] for j in range(r)] for i in range(r)])
    U, sv, Vt = sla.svd(Hk, check_finite=False)
    if sv[0] == 0:
        raise DataError("kung: the impulse response is zero")
    if order is None:
        if threshold is not None:
            n = int(np.count_nonzero(sv > threshold * sv[0]))
        else:
            n = int(np.searchsorted(np.cumsum(sv ** 2) / np.sum(sv ** 2), energy) + 1)
    else:
        n = check_int(order, "order", 1)
        if n > min(r * p, r * m):
            raise DataError(f"order {n} exceeds what {N} impulse-response samples can realise ({min(r * p, r * m)})")
    S = np.sqrt(sv[:n])
    Ob = U[:, :n] * S
    Co = (Vt[:n].T * S).T
    A = (U[:, :n].T @ Hs @ Vt[:n].T) / S[:, None] / S[None, :]
    B = Co[:, :m]
    C = Ob[:p]
    sys = ct.ss(A, B, C, H[0], dt)
    return IdentifiedModel(sys=sys, delay=int(delay), method="kung",
                           settings=dict(order=n, dt=dt, energy=energy, threshold=threshold, samples=N),
                           singular_values=sv)
