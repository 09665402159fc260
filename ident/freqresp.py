"""Non-parametric frequency-response estimates (what the data say, model-free) and a vectorised
frequency response of identified models."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import coherence, csd, welch

from rotorlab.errors import DataError
from rotorlab.lti import as_ss, is_discrete

from ._data import check_io

__all__ = ["FRFEstimate", "welch_frf", "etfe", "model_frf"]


@dataclass(frozen=True)
class FRFEstimate:
    """Non-parametric FRF of a SISO record.

    Attributes
    ----------
    w_rad_s : ndarray
        Frequency grid, rad/s.
    H : ndarray, complex
        FRF estimate (output unit per input unit).
    coherence : ndarray or None
        Magnitude-squared coherence (Welch estimate only).
    reliable : ndarray of bool
        Where the estimate can be trusted: coherence >= threshold (Welch) or input power above a fraction of
        its peak (ETFE). Elsewhere the data say nothing about the plant.
    """

    w_rad_s: np.ndarray
    H: np.ndarray
    coherence: np.ndarray | None
    reliable: np.ndarray


def _siso(u, y):
    u2, y2 = check_io(u, y, min_samples=16, what="frequency-response estimate")
    if u2.shape[1] != 1 or y2.shape[1] != 1:
        raise DataError(f"FRF estimates here are SISO; got {u2.shape[1]} input(s), {y2.shape[1]} output(s): "
                        "call once per input-output pair")
    return u2[:, 0] - u2[:, 0].mean(), y2[:, 0] - y2[:, 0].mean()


def welch_frf(u, y, dt: float, nperseg: int = 512, coherence_threshold: float = 0.6) -> FRFEstimate:
    """H1 estimate ``Puy / Puu`` with Welch averaging (scipy.signal.csd / welch / coherence).

    H1 is unbiased for output noise; in closed loop it is biased towards the inverse controller wherever
    the loop disturbance dominates, which low coherence flags.

    Parameters
    ----------
    u, y : array_like, shape (N,)
        Input and output records of one SISO channel.
    dt : float
        Sample time, s.
    nperseg : int
        Welch segment length, samples (the frequency resolution is ``2 pi / (nperseg dt)`` rad/s).
    coherence_threshold : float
        Coherence below which the estimate is marked unreliable.

    Returns
    -------
    FRFEstimate
        The estimate on the positive Welch frequencies below Nyquist, with coherence and ``reliable``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)
    >>> y = y + 0.2 * np.random.default_rng(1).standard_normal(len(y))  # gyro noise, deg/s

    >>> frf = ident.welch_frf(u, y, dt=0.02, nperseg=256)
    >>> i = np.argmin(np.abs(frf.w_rad_s - 5.0))          # about 5 rad/s
    >>> H = ct.frequency_response(G, frf.w_rad_s[i]).complex.item()
    >>> bool(abs(frf.H[i] / H - 1) < 0.1), bool(frf.reliable[i])
    (True, True)
    """
    uu, yy = _siso(u, y)
    nperseg = min(nperseg, len(uu))
    f, Puu = welch(uu, fs=1 / dt, nperseg=nperseg)
    _, Puy = csd(uu, yy, fs=1 / dt, nperseg=nperseg)
    _, Cuy = coherence(uu, yy, fs=1 / dt, nperseg=nperseg)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Puy / Puu
    return FRFEstimate(2 * np.pi * f, H, Cuy, Cuy >= coherence_threshold)


def etfe(u, y, dt: float, smooth_bins: int = 1, input_floor: float = 1e-3) -> FRFEstimate:
    """Empirical transfer-function estimate ``Y(w) / U(w)`` from the record's DFTs.

    ``smooth_bins > 1`` averages cross- and auto-spectra over that many neighbouring bins (Hann window),
    trading resolution for variance. ``reliable`` marks bins whose smoothed input power exceeds
    ``input_floor`` times its peak.

    Parameters
    ----------
    u, y : array_like, shape (N,)
        Input and output records of one SISO channel.
    dt : float
        Sample time, s.
    smooth_bins : int
        Number of neighbouring bins averaged (1: the raw ratio).
    input_floor : float
        Fraction of the peak smoothed input power below which a bin is unreliable.

    Returns
    -------
    FRFEstimate
        The estimate on the DFT frequencies below Nyquist, with ``reliable``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)
    >>> u = np.random.default_rng(0).standard_normal(4096)
    >>> y = ct.forced_response(G, U=u).y[0]
    >>> frf = ident.etfe(u, y, dt=0.02, smooth_bins=8)
    >>> i = np.argmin(np.abs(frf.w_rad_s - 5.0))
    >>> bool(abs(frf.H[i] / ct.frequency_response(G, frf.w_rad_s[i]).complex.item() - 1) < 0.1)
    True
    """
    uu, yy = _siso(u, y)
    U = np.fft.rfft(uu)
    Y = np.fft.rfft(yy)
    Puy, Puu = Y * U.conj(), np.abs(U) ** 2
    if smooth_bins > 1:
        win = np.hanning(smooth_bins + 2)[1:-1]
        win /= win.sum()
        Puy = np.convolve(Puy, win, mode="same")
        Puu = np.convolve(Puu, win, mode="same")
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Puy / Puu
    w = 2 * np.pi * np.fft.rfftfreq(len(uu), dt)
    return FRFEstimate(w, H, None, Puu >= input_floor * Puu.max())


def model_frf(sys, w_rad_s, delay: int = 0) -> np.ndarray:
    """Frequency response ``(len(w), p, m)`` of a model at ``w_rad_s`` (rad/s), with an optional ``z^-delay``.

    Same result as :func:`rotorlab.lti.freqresp`, but one batched solve over all frequencies instead of a
    loop: the bootstrap evaluates a thousand models on the same grid.

    Parameters
    ----------
    sys : StateSpace
        The model, continuous or discrete.
    w_rad_s : array_like
        Frequencies, rad/s.
    delay : int
        Input delay in samples of a discrete model.

    Returns
    -------
    ndarray, complex, shape (len(w_rad_s), p, m)

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.ss(ct.tf([1.0], [1, 1])), 0.02)
    >>> w = np.array([0.5, 1.0])
    >>> H = ident.model_frf(G, w, delay=3)                    # z^-3 = exp(-3 j w dt) on the unit circle
    >>> H.shape, bool(np.allclose(H[:, 0, 0], ct.frequency_response(G, w).complex.ravel() * np.exp(-3j * w * 0.02)))
    ((2, 1, 1), True)
    """
    s = as_ss(getattr(sys, "sys", sys))
    w = np.atleast_1d(np.asarray(w_rad_s, dtype=float))
    A, B, C, D = (np.asarray(M, dtype=float) for M in (s.A, s.B, s.C, s.D))
    if is_discrete(s):
        pts = np.exp(1j * w * float(s.dt))
    else:
        pts = 1j * w
    n = A.shape[0]
    if n == 0:
        G = np.broadcast_to(D, (len(w),) + D.shape).astype(complex)
    else:
        M = pts[:, None, None] * np.eye(n) - A
        G = C @ np.linalg.solve(M, np.broadcast_to(B.astype(complex), (len(w),) + B.shape)) + D
    if delay:
        if not is_discrete(s):
            raise DataError("a delay in samples needs a discrete model")
        G = G * (pts ** -delay)[:, None, None]
    return G
