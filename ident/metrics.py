"""Fit metrics and simulation of identified models: the papers' VAF and x0-aware simulation."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from rotorlab.errors import DataError

from ._data import as_columns
from .model import IdentifiedModel, lsim_fast, observability_sequence

__all__ = ["vaf", "simulate"]


def vaf(y, y_hat) -> np.ndarray:
    """Variance accounted for, percent per output: ``max(0, (1 - var(y - y_hat) / var(y)) * 100)``.

    Parameters
    ----------
    y, y_hat : array_like, shape (N,) or (N, p)
        Measured (or reference) and model outputs.

    Returns
    -------
    ndarray, shape (p,)

    Examples
    --------
    >>> from rotorlab import ident
    >>> y = np.sin(np.linspace(0, 10, 500))
    >>> print(ident.vaf(y, 0.9 * y))            # 10 % gain error: 1 - 0.01 var(y) / var(y)
    [99.]
    """
    y2, yh = as_columns(y, "y"), as_columns(y_hat, "y_hat")
    if y2.shape != yh.shape:
        raise DataError(f"y has shape {y2.shape} but y_hat has {yh.shape}; compare outputs of the same record")
    vy = np.var(y2, axis=0)
    if np.any(vy == 0):
        raise DataError("VAF is undefined for a constant output channel (zero variance)")
    return np.maximum(0.0, (1.0 - np.var(y2 - yh, axis=0) / vy) * 100.0)


def simulate(model: IdentifiedModel, u, x0=None, y=None, n_x0: int | None = None) -> np.ndarray:
    """Noise-free output of an identified model, delay included.

    Parameters
    ----------
    model : IdentifiedModel
    u : array_like, shape (N,) or (N, m)
    x0 : None, array_like or "estimate"
        Initial state of ``model.sys`` (delay line empty) or of ``model.with_delay()``; ``"estimate"``
        fits the latter (delay-line contents included) by least squares to ``y`` over the first ``n_x0``
        samples (default ``10 n + 50``), so a validation record that starts away from rest is compared
        fairly.
    y : array_like, optional
        Measured output, needed for ``x0="estimate"``.

    Returns
    -------
    ndarray, shape (N, p)

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)

    >>> m = ident.pbsid(u, y, order=2, past=20, future=10, dt=0.02)
    >>> print(np.round(ident.vaf(y, ident.simulate(m, u)), 3))
    [100.]
    """
    u2 = as_columns(u, "u")
    full = model.with_delay()  # the delay line is part of the state, so its unknown contents are fitted too
    A, B, C, D = (np.asarray(M, dtype=float) for M in (full.A, full.B, full.C, full.D))
    n = A.shape[0]
    if isinstance(x0, str):
        if x0 != "estimate":
            raise DataError(f"x0 must be None, an array or 'estimate'; got {x0!r}")
        if y is None:
            raise DataError("x0='estimate' needs the measured output y")
        y2 = as_columns(y, "y")
        if len(y2) != len(u2):
            raise DataError(f"u has {len(u2)} samples but y has {len(y2)}")
        k = min(len(u2), n_x0 if n_x0 is not None else 10 * n + 50)
        resid = y2[:k] - lsim_fast(A, B, C, D, u2[:k])
        O = observability_sequence(A, C, k)  # (k, p, n)
        x0 = sla.lstsq(O.reshape(-1, n), resid.ravel())[0]
    elif x0 is not None:
        x0 = np.asarray(x0, dtype=float).ravel()
        if x0.size == model.sys.nstates and n != x0.size:
            # a state of the delay-free model: the delay line (ordered first by with_io_delay) starts empty
            x0 = np.concatenate([np.zeros(n - x0.size), x0])
        elif x0.size != n:
            raise DataError(f"x0 has {x0.size} entries; the model has {model.sys.nstates} states "
                            f"({n} with its {model.delay}-sample delay line)")
    return lsim_fast(A, B, C, D, u2, x0)
