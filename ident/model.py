"""The one result type of every rotorlab identification method (black-box and grey-box).

An identified model keeps the plant with its input delay *removed* (``sys``), the delay in samples next to
it, and what produced it, so that a user can read the settings back and simulate the model exactly as it
was fitted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control as ct
import numpy as np
from scipy.signal import dlsim, lfilter, ss2tf

from rotorlab.lti import as_ss, is_discrete, with_io_delay

__all__ = ["IdentifiedModel"]


@dataclass(frozen=True)
class IdentifiedModel:
    """An identified LTI model.

    Attributes
    ----------
    sys : control.StateSpace
        Deterministic part ``u -> y`` with the input delay removed (discrete with ``dt`` in s, or continuous).
    delay : int
        Input delay in samples (``z^-delay`` on every input); 0 when none.
    method : str
        Name of the method that produced the model (``"moesp"``, ``"pbsid"``, ``"kung"``, ...).
    settings : dict
        The settings the method was called with (order, horizons, ...), for reproducibility.
    K : ndarray or None
        Innovation (Kalman) gain of the innovation form ``x+ = A x + B u + K e``, ``y = C x + D u + e``.
    noise_cov : ndarray or None
        Covariance of the innovation ``e`` (p x p).
    singular_values : ndarray or None
        Singular values the order was read from (subspace and realisation methods).
    extra : dict
        Method-specific extras (fit residuals, x0, parameter covariances, ...).
    """

    sys: ct.StateSpace
    delay: int = 0
    method: str = ""
    settings: dict = field(default_factory=dict)
    K: np.ndarray | None = None
    noise_cov: np.ndarray | None = None
    singular_values: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def dt(self):
        """Sample time in s (0 for continuous time)."""
        return self.sys.dt

    @property
    def order(self) -> int:
        return self.sys.nstates

    def with_delay(self) -> ct.StateSpace:
        """The model with its ``z^-delay`` input delay put back (a discrete StateSpace)."""
        if self.delay == 0:
            return self.sys
        if not is_discrete(self.sys):
            raise ValueError("a delay in samples needs a discrete model; this one is continuous")
        return with_io_delay(self.sys, self.delay * float(self.sys.dt))

    def innovation_form(self) -> ct.StateSpace:
        """The innovation-form model ``[u; e] -> y`` (delay removed), or ``None`` without ``K``."""
        if self.K is None:
            return None
        s = as_ss(self.sys)
        p = s.noutputs
        B = np.hstack([s.B, self.K])
        D = np.hstack([s.D, np.eye(p)])
        return ct.ss(s.A, B, s.C, D, s.dt)

    def simulate(self, u, x0=None) -> np.ndarray:
        """Noise-free output of the model (delay included) for input ``u``.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, m)
            Input samples at ``dt``; the first ``delay`` delayed inputs are taken as zero.
        x0 : array_like, optional
            Initial state of ``sys`` (delay-free state), zero by default.

        Returns
        -------
        ndarray, shape (N, p)
        """
        if not is_discrete(self.sys):
            raise ValueError("simulate() needs a discrete model; discretise a continuous one with c2d_zoh first")
        s = as_ss(self.sys)
        u = np.asarray(u, dtype=float)
        u2 = u.reshape(len(u), -1)
        if u2.shape[1] != s.ninputs:
            raise ValueError(f"model has {s.ninputs} inputs, u has {u2.shape[1]} columns")
        d = int(self.delay)
        if d:
            u2 = np.vstack([np.zeros((d, u2.shape[1])), u2[: len(u2) - d]])
        return _dlsim(s, u2, x0)


def _dlsim(s: ct.StateSpace, u: np.ndarray, x0=None) -> np.ndarray:
    """Discrete simulation ``x+ = A x + B u, y = C x + D u``; ``u`` (N, m) -> (N, p)."""
    A, B, C, D = (np.asarray(M, dtype=float) for M in (s.A, s.B, s.C, s.D))
    return lsim_fast(A, B, C, D, u, x0)


# Above this order the per-channel transfer-function coefficients lose too much precision for lfilter.
_MAX_TF_ORDER = 10


def lsim_fast(A, B, C, D, u, x0=None) -> np.ndarray:
    """Simulate a discrete state-space model, ``u`` (N, m) -> ``y`` (N, p).

    scipy.signal.dlsim steps through time in a Python loop; the bootstrap runs a thousand such simulations,
    so for the low orders identification produces the response is built from
    compiled all-pole filtering (:func:`state_regressors`). Higher orders fall back to dlsim, whose state
    recursion stays well conditioned where polynomial coefficients would not.
    """
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    n = A.shape[0]
    N, p = len(u), C.shape[0]
    y = u @ D.T
    if n == 0:
        return y
    if n > _MAX_TF_ORDER:
        x0v = np.zeros(n) if x0 is None else np.asarray(x0, float).ravel()
        _, yd, _ = dlsim((A, B, C, D, 1.0), u, x0=x0v)
        return np.asarray(yd).reshape(N, p)
    den, W = _adjugate_terms(A, C)
    WB = W @ B  # (n, p, m): C M_k B
    for j in range(u.shape[1]):
        v = lfilter([1.0], den, u[:, j])
        for k in range(n):
            y[k + 1:] += np.outer(v[: N - k - 1], WB[k, :, j])
    if x0 is not None and np.any(x0):
        y += observability_sequence(A, C, N) @ np.asarray(x0, float).ravel()
    return y


def free_response(A, C, x0, N: int) -> np.ndarray:
    """``C A^k x0`` for ``k = 0..N-1``, shape (N, p), computed as the impulse response of ``(A, A x0, C)``.

    ``C A^(k-1) (A x0)`` is that system's k-th Markov parameter, so one lfilter per output replaces the
    Python loop over time.
    """
    n = A.shape[0]
    if n > _MAX_TF_ORDER:
        out = np.empty((N, C.shape[0]))
        x = np.array(x0, dtype=float)
        for k in range(N):
            out[k] = C @ x
            x = A @ x
        return out
    num, den = ss2tf(A, (A @ x0).reshape(n, 1), C, np.zeros((C.shape[0], 1)))
    imp = np.zeros(N)
    imp[0] = 1.0
    out = np.column_stack([lfilter(num[i], den, imp) for i in range(C.shape[0])])
    out += C @ x0 * imp[:, None]
    return out


def _adjugate_terms(A, C):
    """``den`` (characteristic polynomial) and ``W[k] = C M_k`` with ``adj(zI - A) = sum_k z^(n-1-k) M_k``
    (Faddeev-LeVerrier: ``M_0 = I``, ``M_k = A M_(k-1) + den[k] I``)."""
    n = A.shape[0]
    den = np.poly(A).real
    W = np.empty((n, C.shape[0], n))
    M = np.eye(n)
    for k in range(n):
        if k:
            M = A @ M + den[k] * np.eye(n)
        W[k] = C @ M
    return den, W


def state_regressors(A, C, u) -> np.ndarray:
    """Sensitivities ``R[t, q, i, j] = d y_q(t) / d B[i, j]`` of ``y = C (zI - A)^-1 B u`` (zero initial state).

    The output is linear in ``B``, so these are the least-squares regressors for ``B`` (and, with the
    innovations as input, for ``K``). All ``n m p`` of them come from one all-pole filtering per input:
    ``C (zI - A)^-1 e_i = sum_k (C M_k e_i) z^-(k+1) / den(z^-1)`` (one lfilter per input and one product,
    instead of ``n m`` state-space simulations).
    """
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    n, p = A.shape[0], C.shape[0]
    N, m = u.shape
    if n > _MAX_TF_ORDER:
        eye = np.eye(n)
        out = np.empty((N, p, n, m))
        for i in range(n):
            for j in range(m):
                out[:, :, i, j] = _dlsim(ct.ss(A, eye[:, [i]], C, np.zeros((p, 1)), 1.0), u[:, [j]])
        return out
    den, W = _adjugate_terms(A, C)
    out = np.empty((N, p, n, m))
    for j in range(m):
        v = lfilter([1.0], den, u[:, j])
        lagged = np.zeros((N, n))  # v(t - 1 - k)
        for k in range(n):
            lagged[k + 1:, k] = v[: N - k - 1]
        out[:, :, :, j] = np.einsum("tk,kqi->tqi", lagged, W)
    return out


def observability_sequence(A, C, N: int) -> np.ndarray:
    """``O[t] = C A^t`` for ``t = 0..N-1``, shape (N, p, n): the regressors of the initial state."""
    n = A.shape[0]
    if n > _MAX_TF_ORDER:
        return np.stack([free_response(A, C, e, N) for e in np.eye(n)], axis=2)
    # C A^t = C A^(t-1) A: the t >= 1 terms are the impulse response of (A, A, C)
    imp = np.zeros(N)
    imp[0] = 1.0
    R = state_regressors(A, C, imp)[:, :, :, 0] @ A
    R[0] = C
    return R
