"""Rotor-wake recirculation on an indoor test-bed as a moment on the airframe about the rig axis.

The seeded low-frequency moment comes from :class:`rotorlab.sim.disturbances.recirculation_torque.RecirculationTorque`
(one axis: the rig's); it is written into ``xfrc_applied`` of the airframe each control tick (held over the
tick, like the wind). Positive moments raise the rig angle (the aerospace sign of that axis).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from rotorlab.errors import ConfigError, RotorlabError
from rotorlab.scenes import RIG_AXES
from rotorlab.sim.disturbances.base import Disturbance
from rotorlab.sim.disturbances.recirculation_torque import RecirculationTorque


class RecirculationMoment(Disturbance):
    """Recirculation moment on the rig.

    Parameters
    ----------
    rms_Nm : float
        Stationary RMS of the moment, N m.
    duration_s : float
        Run length the record must cover, s.
    cutoff_hz : float
        Low-pass corner of the moment, Hz.
    """

    name = "recirculation"
    scenes = tuple(RIG_AXES)
    columns = {"recirc_moment": "N m"}
    stage = mujoco.mjtStage.mjSTAGE_ACC  # xfrc_applied

    def __init__(self, rms_Nm: float, duration_s: float, cutoff_hz: float = 1.5):
        RecirculationTorque(rms_Nm, cutoff_hz, n_axes=1)  # validates
        if not duration_s > 0:
            raise ConfigError(field="duration_s", expected="the run length in s (> 0)", got=duration_s)
        self.rms_Nm, self.duration_s, self.cutoff_hz = float(rms_Nm), float(duration_s), float(cutoff_hz)

    def reset(self, sim, rng) -> None:
        self._dt = sim.control_dt_s
        n = int(math.ceil(self.duration_s / self._dt)) + 1
        self._m = RecirculationTorque(self.rms_Nm, self.cutoff_hz, n_axes=1, rng=rng).generate(n, self._dt)[:, 0]
        self._axis = np.asarray(RIG_AXES[sim.scene.name][1], dtype=float)
        self._body = sim._airframe

    def moment(self, t: float) -> float:
        k = int(round(t / self._dt))
        if k >= len(self._m):
            raise RotorlabError(f"the recirculation record is {self.duration_s:g} s long; the run asked for "
                                f"t = {t:.3f} s (give the disturbance the run's duration)")
        return float(self._m[k])

    def update(self, sim, t: float) -> None:
        sim.data.xfrc_applied[self._body, 3:6] += self.moment(t) * self._axis

    def values(self, sim) -> dict:
        return {"recirc_moment": self.moment(sim.time)}


__all__ = ["RecirculationMoment"]
