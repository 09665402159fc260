"""Discrete "1 - cosine" gust: the standard deterministic gust shape (MIL-F-8785C discrete gust, CS-25.341).

    v(t) = amplitude / 2 (1 - cos(2 pi (t - t_start) / duration_s))   for t_start <= t <= t_start + duration_s
    v(t) = 0                                                           otherwise

Zero outside the window, peak ``amplitude`` at the middle, and C1: both the value and the slope are zero at the
window edges, so it excites no artificial step in the vehicle's response.
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError


def one_minus_cosine(t, t_start: float, duration_s: float, amplitude: float, direction=None) -> np.ndarray:
    """Gust velocity (or any quantity) at times ``t`` (s).

    Parameters
    ----------
    t : array
        Times, s.
    t_start, duration_s : float
        Start and full length of the gust, s.
    amplitude : float
        Peak value (m/s for a gust velocity).
    direction : (3,) array, optional
        Direction of the gust; normalised, and the result is ``(len(t), 3)``. Without it, ``(len(t),)``.
    """
    if not duration_s > 0:
        raise ConfigError(field="duration_s", expected="a duration > 0 s", got=duration_s)
    t = np.asarray(t, dtype=float)
    phase = (t - t_start) / duration_s
    inside = (phase >= 0.0) & (phase <= 1.0)
    v = np.where(inside, 0.5 * amplitude * (1.0 - np.cos(2.0 * np.pi * phase)), 0.0)
    if direction is None:
        return v
    d = np.asarray(direction, dtype=float).reshape(3)
    norm = np.linalg.norm(d)
    if norm == 0:
        raise ConfigError(field="direction", expected="a non-zero 3-vector", got=d.tolist())
    return v[..., None] * (d / norm)
