"""Dryden continuous turbulence (MIL-F-8785C low altitude) as wind on the vehicle.

The gust velocities come from :class:`rotorlab.sim.disturbances.dryden.DrydenTurbulence` seeded with this
disturbance's own generator; ``u`` is along the mean wind (the direction the air moves), ``v`` horizontal to its
right, ``w`` down, with the standard's gust gradients ``p_g, q_g, r_g`` over the vehicle's span: the air's
rotation, which the rotors feel through their inflow and disc-tilt damping
(:func:`rotorlab.sim.simulator.set_air_motion`). The record is drawn once at reset for the whole run, so a seed
gives the same gusts whatever else the run contains.
"""

from __future__ import annotations

import numpy as np

from rotorlab.sim.disturbances.dryden import DrydenTurbulence
from rotorlab.sim.disturbances.mean_wind import WIND_COLUMNS, SampledWind, toward_ned
from rotorlab.sim.frames import NED_TO_ZUP, RAD2DEG


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
    rotates_air = True
    #: the total wind (:class:`WindDisturbance`) and this record's air rotation about north, east and down
    columns = {**WIND_COLUMNS, "air_rate_n": "deg/s", "air_rate_e": "deg/s", "air_rate_d": "deg/s"}

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
        self.span_m = None  # the vehicle's, at reset

    def reset(self, sim, rng) -> None:
        """Draw the record (:class:`SampledWind`) with the gust gradients over the vehicle's span, tip to tip
        ``2 (arm + rotor radius)`` (the standard's ``b``: the size over which the air's rotation is felt)."""
        v = sim.vehicle
        self.span_m = 2.0 * (v.arm_m + v.rotor.radius_m)
        super().reset(sim, rng)

    def update(self, sim, t: float) -> None:
        k = self._index(t)
        sim.wind_world += self._w_zup[k]
        sim.air_rate_world += self._rate_zup[k]

    def values(self, sim) -> dict:
        out = super().values(sim)
        out["air_rate_n"], out["air_rate_e"], out["air_rate_d"] = self._rate_dps[self._index(sim.time)]
        return out

    def generator(self, rng) -> DrydenTurbulence:
        return DrydenTurbulence(self.mean_speed_mps, self.altitude_m, self.sigma_mps, rng=rng)

    def record_ned(self, rng, n: int, dt: float) -> np.ndarray:
        """The gust velocities (NED); the air's rotation over :attr:`span_m` that goes with them (the standard's
        gust gradients) is kept for :meth:`update` in the same axes."""
        uvw, pqr = self.generator(rng).generate_with_rates(n, dt, self.span_m)
        rate_ned = pqr @ self._axes.T
        self._rate_zup = rate_ned * NED_TO_ZUP
        self._rate_dps = (rate_ned * RAD2DEG).tolist()  # the logged rotation, converted once for the record
        return uvw @ self._axes.T


__all__ = ["DrydenWind", "turbulence_axes_ned"]
