"""Steady mean wind, and the shared plumbing of every wind disturbance.

Wind enters the physics only through ``sim.wind_world`` (m/s, MuJoCo world, z up): the simulator turns it into
fuselage drag (MuJoCo's fluid model with ``opt.wind``) and rotor inflow / H-force (the rotor aero actuators).
Wind disturbances add up; each logs the *total* wind as ground truth in ``wind_u, wind_v, wind_w`` (m/s, NED:
north, east, down, the frame of the logged ``x, y, z``), so the log is the same whichever of them is listed first.

Directions are meteorological: ``from_deg`` is where the wind comes from, clockwise from north (the world x
axis, the vehicle's nose at the hover keyframe). ``from_deg = 0`` is a headwind: it pitches a hovering
vehicle nose up (H-force above the CG and blade flapping), so the position hold answers nose into the wind.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from rotorlab.errors import ConfigError, RotorlabError
from rotorlab.sim.disturbances.base import Disturbance
from rotorlab.sim.frames import NED_TO_ZUP

WIND_COLUMNS = {"wind_u": "m/s", "wind_v": "m/s", "wind_w": "m/s"}


def toward_ned(from_deg: float) -> np.ndarray:
    """Unit horizontal vector (NED) along which air coming from ``from_deg`` moves."""
    a = math.radians(from_deg)
    return -np.array([math.cos(a), math.sin(a), 0.0])


def total_wind_ned(winds, t: float):
    """The summed wind (m/s, NED) of wind disturbances over the control period starting at ``t`` (0 if none)."""
    w = 0
    for d in winds:
        w = w + d.wind_ned(t)
    return w


class WindDisturbance(Disturbance):
    """A wind disturbance. Subclasses define ``wind_ned(t) -> (3,)``: the wind (m/s, NED) over the control
    period that starts at ``t`` (s)."""

    columns = WIND_COLUMNS
    stage = mujoco.mjtStage.mjSTAGE_VEL  # the fuselage drag under opt.wind; the rotor aero controls come later

    def update(self, sim, t: float) -> None:
        sim.wind_world += self.wind_ned(t) * NED_TO_ZUP

    def wind_ned_floats(self, t: float) -> list:
        """:meth:`wind_ned` as a list of floats, for :meth:`values` every tick (a wind kept as a record or a
        constant keeps it as floats too, converted once)."""
        return self.wind_ned(t).tolist()

    def values(self, sim) -> dict:
        # the total wind the coming control period is flown in (every wind disturbance writes the same sum)
        winds = sim.wind_disturbances
        if winds[0] is not self:
            return {}  # the first wind disturbance logs the sum
        # total_wind_ned's sum in floats, the same additions from 0 in the same order: this runs every tick, and
        # numpy's per-call cost on 3-vectors is several times the arithmetic
        t = sim.time
        u = v = w = 0
        for d in winds:
            a, b, c = d.wind_ned_floats(t)
            u, v, w = u + a, v + b, w + c
        return {"wind_u": u, "wind_v": v, "wind_w": w}


class SampledWind(WindDisturbance):
    """Wind drawn as a whole record at :meth:`reset` (seeded) and played back one sample per control tick.
    Subclasses define ``record_ned(rng, n, dt) -> (n, 3)``: ``n`` NED samples (m/s) every ``dt`` s."""

    def __init__(self, duration_s: float):
        if not duration_s > 0:
            raise ConfigError(field="duration_s", expected="the run length in s (> 0)", got=duration_s)
        self.duration_s = float(duration_s)
        self._dt = None
        self._w = None

    def reset(self, sim, rng) -> None:
        self._dt = sim.control_dt_s
        n = int(math.ceil(self.duration_s / self._dt)) + 1
        self._w = self.record_ned(rng, n, self._dt)
        self._w_zup = self._w * NED_TO_ZUP  # update's conversion, made once for the record
        self._w_rows = self._w.tolist()

    def _index(self, t: float) -> int:
        k = int(round(t / self._dt))
        if k >= len(self._w):
            raise RotorlabError(f"the '{self.name}' record is {self.duration_s:g} s long; the run asked for t = {t:.3f} s "
                                "(give the disturbance the run's duration)")
        return k

    def wind_ned(self, t: float) -> np.ndarray:
        return self._w[self._index(t)]

    def wind_ned_floats(self, t: float) -> list:
        return self._w_rows[self._index(t)]

    def update(self, sim, t: float) -> None:
        sim.wind_world += self._w_zup[self._index(t)]


class MeanWind(WindDisturbance):
    """Constant wind.

    Parameters
    ----------
    speed_mps : float
        Horizontal wind speed, m/s (the A2-MINI/B flight test: 2.5).
    from_deg : float
        Where it comes from, deg clockwise from north (0: headwind).
    vertical_mps : float
        Vertical air velocity, m/s, positive down (NED).
    """

    name = "mean-wind"

    def __init__(self, speed_mps: float, from_deg: float = 0.0, vertical_mps: float = 0.0):
        if not speed_mps >= 0:
            raise ConfigError(field="speed_mps", expected="a speed >= 0 m/s", got=speed_mps)
        self.speed_mps = float(speed_mps)
        self.from_deg = float(from_deg)
        self._w = speed_mps * toward_ned(from_deg) + np.array([0.0, 0.0, float(vertical_mps)])
        self._w_zup = self._w * NED_TO_ZUP  # update's conversion, made once
        self._w_floats = self._w.tolist()

    def wind_ned(self, t: float) -> np.ndarray:
        return self._w

    def wind_ned_floats(self, t: float) -> list:
        return self._w_floats

    def update(self, sim, t: float) -> None:
        sim.wind_world += self._w_zup


__all__ = ["MeanWind", "WindDisturbance", "SampledWind", "WIND_COLUMNS", "toward_ned", "total_wind_ned"]
