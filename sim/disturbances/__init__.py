"""Disturbances: seeded signal generators (pure numpy/scipy: Dryden turbulence, the 1-cosine gust shape, the
recirculation torque) and the disturbances that act through the physics (one file each, named after its class,
following :class:`rotorlab.sim.disturbances.base.Disturbance`).

:data:`DISTURBANCES` maps each disturbance's ``name`` to its class: a new disturbance is one new file plus one
entry here (tests/test_disturbances.py walks the table).
"""

from rotorlab.sim.disturbances.base import Disturbance
from rotorlab.sim.disturbances.cosine_gust import CosineGust
from rotorlab.sim.disturbances.dryden import (
                                               DrydenTurbulence,
                                               dryden_psd_rates,
                                               dryden_psd_u,
                                               dryden_psd_v,
                                               dryden_psd_w,
                                               low_altitude_scales,
)
from rotorlab.sim.disturbances.dryden_wind import DrydenWind
from rotorlab.sim.disturbances.gust import one_minus_cosine
from rotorlab.sim.disturbances.input_disturbance_step import InputDisturbanceStep
from rotorlab.sim.disturbances.mean_wind import MeanWind, SampledWind, WindDisturbance
from rotorlab.sim.disturbances.recirculation_moment import RecirculationMoment
from rotorlab.sim.disturbances.recirculation_torque import RecirculationTorque
from rotorlab.sim.disturbances.rope_pull import RopePull

#: disturbance name -> class
DISTURBANCES = {cls.name: cls for cls in (MeanWind, DrydenWind, CosineGust, RecirculationMoment, RopePull,
                                             InputDisturbanceStep)}

__all__ = ["DISTURBANCES", "Disturbance", "WindDisturbance", "SampledWind", "MeanWind", "DrydenWind", "CosineGust",
           "RecirculationMoment", "RopePull", "InputDisturbanceStep", "DrydenTurbulence", "dryden_psd_rates", "dryden_psd_u",
           "dryden_psd_v", "dryden_psd_w", "low_altitude_scales", "one_minus_cosine", "RecirculationTorque"]
