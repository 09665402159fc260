"""Discrete 1-cosine gust (MIL-F-8785C) as wind on the vehicle, shape from
:func:`rotorlab.sim.disturbances.gust.one_minus_cosine`."""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.sim.disturbances.gust import one_minus_cosine
from rotorlab.sim.disturbances.mean_wind import WindDisturbance, toward_ned


class CosineGust(WindDisturbance):
    """One 1-cosine gust.

    Parameters
    ----------
    t_start_s, duration_s : float
        Start and full length of the gust, s.
    amplitude_mps : float
        Peak gust speed, m/s.
    from_deg : float
        Horizontal direction it comes from (deg clockwise from north; 0: headwind, pitches nose up).
    """

    name = "cosine-gust"

    def __init__(self, t_start_s: float, duration_s: float, amplitude_mps: float, from_deg: float = 0.0):
        if not t_start_s >= 0:
            raise ConfigError(field="t_start_s", expected="a start time >= 0 s", got=t_start_s)
        one_minus_cosine(0.0, t_start_s, duration_s, amplitude_mps)  # validates the duration
        self.t_start_s, self.duration_s = float(t_start_s), float(duration_s)
        self.amplitude_mps = float(amplitude_mps)
        self._dir = toward_ned(from_deg)

    def wind_ned(self, t: float) -> np.ndarray:
        return float(one_minus_cosine(t, self.t_start_s, self.duration_s, self.amplitude_mps)) * self._dir


__all__ = ["CosineGust"]
