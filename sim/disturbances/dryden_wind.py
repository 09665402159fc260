"""Dryden continuous turbulence (MIL-F-8785C low altitude) as wind on the vehicle.

The gust velocities come from :class:`rotorlab.sim.disturbances.dryden.DrydenTurbulence` seeded with this
disturbance's own generator; ``u`` is along the mean wind (the direction the air moves), ``v`` horizontal to its
right, ``w`` down. The record is drawn once at reset for the whole run, so a seed gives the same gusts
whatever else the run contains.
"""

from __future__ import annotations

import numpy as np

from rotorlab.sim.disturbances.dryden import DrydenTurbulence
from rotorlab.sim.disturbances.mean_wind import SampledWind, toward_ned


def turbulence_axes_ned(from_deg: float) -> np.ndarray:
    """3x3 matrix whose columns are the turbulence axes u (along the mean wind), v (right of it), w (down), NED."""
    u = toward_ned(from_deg)
    v = np.array([-u[1], u[0], 0.0])
    return np.column_stack([u, v, [0.0, 0.0, 1.0]])


class DrydenWind(SampledWind):
    """Seeded Dryden turbulence.

    Parameters
    ----------
    mean_speed_mps : float
        Mean wind the turbulence is advected by (> 0; Taylor's hypothesis in hover), m/s.
    altitude_m : float
        Height for the standard's length scales, m.
    duration_s : float
        Run length the record must cover, s.
    from_deg : float
        Mean-wind direction (where it comes from, deg clockwise from north).
    sigma_mps : float or (3,), optional
        Intensities (u, v, w), m/s; default the standard's, from the mean wind as the wind at 20 ft.
    """

    name = "dryden"

    def __init__(self, mean_speed_mps: float, altitude_m: float, duration_s: float, from_deg: float = 0.0,
                 sigma_mps=None):
        super().__init__(duration_s)
        # validates V > 0 and the intensities at construction, not mid-run
        DrydenTurbulence(mean_speed_mps, altitude_m, sigma_mps)
        self.mean_speed_mps = float(mean_speed_mps)
        self.altitude_m = float(altitude_m)
        self.from_deg = float(from_deg)
        self.sigma_mps = sigma_mps
        self._axes = turbulence_axes_ned(from_deg)

    def generator(self, rng) -> DrydenTurbulence:
        return DrydenTurbulence(self.mean_speed_mps, self.altitude_m, self.sigma_mps, rng=rng)

    def record_ned(self, rng, n: int, dt: float) -> np.ndarray:
        return self.generator(rng).generate(n, dt) @ self._axes.T


__all__ = ["DrydenWind", "turbulence_axes_ned"]
