"""Disturbance signal generators (seeded, pure numpy/scipy): Dryden turbulence, 1-cosine gust, indoor
recirculation moments. The simulator turns these signals into forces and moments."""

from rotorlab.sim.disturbances.dryden import (DrydenTurbulence, dryden_psd_u, dryden_psd_v, dryden_psd_w,
                                               low_altitude_scales)
from rotorlab.sim.disturbances.gust import one_minus_cosine
from rotorlab.sim.disturbances.recirculation import RecirculationTorque

__all__ = ["DrydenTurbulence", "dryden_psd_u", "dryden_psd_v", "dryden_psd_w", "low_altitude_scales",
           "one_minus_cosine", "RecirculationTorque"]
