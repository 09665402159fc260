"""The discrete filters the autopilots run, written once as coefficient formulas, each with its transfer function.

Two filters cover both autopilots:

* the second-order Butterworth low-pass of PX4's ``math::LowPassFilter2p``
  (PX4 src/lib/mathlib/math/filter/LowPassFilter2p.hpp, the filter ArduPilot's ``LowPassFilter2p`` also uses):
  bilinear transform with the cutoff pre-warped, ``Omega = tan(pi fc / fs)``, ``c = 1 + 2 cos(pi/4) Omega + Omega^2``,
  ``b0 = b2 = Omega^2 / c``, ``b1 = 2 b0``, ``a1 = 2 (Omega^2 - 1) / c``, ``a2 = (1 - 2 cos(pi/4) Omega + Omega^2) / c``,
  run as ``H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``. PX4 turns it off (``H = 1``) when
  ``fc <= 0`` or ``fc >= fs / 2``; newer PX4 raises a cutoff below 5 Hz to 5 Hz (not modelled: every default is
  above 5 Hz). Its gain at ``fc`` is exactly ``1/sqrt(2)`` (-3 dB) thanks to the pre-warping.
* the first-order "alpha" low-pass of PX4's ``AlphaFilter`` (src/lib/mathlib/math/filter/AlphaFilter.hpp,
  ``update(sample, dt)``) and of ArduPilot's ``calc_lowpass_alpha_dt`` (libraries/AP_Math/AP_Math.cpp, used by
  ``AC_PID`` for its target, error and derivative filters): ``alpha = dt / (dt + 1 / (2 pi fc))``,
  ``y[k] = y[k-1] + alpha (u[k] - y[k-1])``, so ``H(z) = alpha z / (z - (1 - alpha))``; ``fc <= 0`` gives
  ``alpha = 1`` (no filter). Its -3 dB frequency lies below ``fc`` (a backward-Euler RC): 17.5 Hz for a 20 Hz
  cutoff at 400 Hz, within 2 % of ``fc`` for ``fc <= fs / 200``.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np

__all__ = ["butter2_on", "butter2_coeffs", "butter2_ss", "alpha_lowpass", "alpha_ss"]


def butter2_on(sample_hz: float, cutoff_hz: float) -> bool:
    """Whether PX4's ``LowPassFilter2p`` filters at all: a cutoff of 0 (or below), or at or above the Nyquist
    frequency, switches it off (pass-through).

    Examples
    --------
    >>> butter2_on(250.0, 30.0), butter2_on(250.0, 0.0), butter2_on(250.0, 125.0)
    (True, False, False)
    """
    return 0.0 < cutoff_hz < sample_hz / 2 and sample_hz > 0


def butter2_coeffs(sample_hz: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients ``(b, a)`` of PX4's ``LowPassFilter2p`` (``a[0] = 1``); ``([1, 0, 0], [1, 0, 0])`` when off.

    Examples
    --------
    >>> b, a = butter2_coeffs(400.0, 40.0)
    >>> round(float(b.sum() / a.sum()), 12)  # unit DC gain
    1.0
    """
    if not butter2_on(sample_hz, cutoff_hz):
        return np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    om = math.tan(math.pi * cutoff_hz / sample_hz)
    k = 2.0 * math.cos(math.pi / 4.0) * om
    c = 1.0 + k + om * om
    b0 = om * om / c
    return np.array([b0, 2.0 * b0, b0]), np.array([1.0, 2.0 * (om * om - 1.0) / c, (1.0 - k + om * om) / c])


def butter2_ss(sample_hz: float, cutoff_hz: float) -> ct.StateSpace:
    """:func:`butter2_coeffs` as a discrete StateSpace at ``dt = 1 / sample_hz`` (0 states when the filter is off)."""
    dt = 1.0 / sample_hz
    b, a = butter2_coeffs(sample_hz, cutoff_hz)
    if a[1] == 0.0 and a[2] == 0.0 and b[1] == 0.0:
        return ct.ss([], [], [], [[b[0]]], dt)
    # direct form II states (w[k-1], w[k-2]), the state PX4's apply() keeps
    A = np.array([[-a[1], -a[2]], [1.0, 0.0]])
    B = np.array([[1.0], [0.0]])
    C = np.array([[b[1] - b[0] * a[1], b[2] - b[0] * a[2]]])
    D = np.array([[b[0]]])
    return ct.ss(A, B, C, D, dt)


def alpha_lowpass(dt_s: float, cutoff_hz: float) -> float:
    """``alpha = dt / (dt + 1 / (2 pi fc))`` of PX4's AlphaFilter and ArduPilot's ``calc_lowpass_alpha_dt``.

    Examples
    --------
    >>> round(alpha_lowpass(0.0025, 0.0), 3)  # off
    1.0
    """
    if cutoff_hz <= 0 or dt_s <= 0:
        return 1.0
    return dt_s / (dt_s + 1.0 / (2.0 * math.pi * cutoff_hz))


def alpha_ss(dt_s: float, cutoff_hz: float) -> ct.StateSpace:
    """``alpha z / (z - (1 - alpha))`` as a discrete StateSpace (state: the previous output ``y[k-1]``)."""
    a = alpha_lowpass(dt_s, cutoff_hz)
    if a == 1.0:
        return ct.ss([], [], [], [[1.0]], dt_s)
    # y[k] = (1-a) y[k-1] + a u[k]; state x[k] = y[k-1]
    return ct.ss([[1.0 - a]], [[a]], [[1.0 - a]], [[a]], dt_s)
