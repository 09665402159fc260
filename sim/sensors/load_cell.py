"""Thrust-stand load cell: ``thrust`` (N, up) and rotor drag ``torque`` (N m, counter-clockwise from above).

The cell is a stiff spring pair under the motor mount (``rotorlab.scenes``): the reading is the spring
deflection (MuJoCo ``jointpos`` sensors) times its stiffness, tared so that it reads the force the rotor
produces: the mount's weight, which the cell carries at rest, is added back.
"""

from __future__ import annotations

import numpy as np

from rotorlab.scenes import LOAD_CELL_K, LOAD_CELL_MASS_KG
from rotorlab.sim.sensors.base import Sensor


class LoadCell(Sensor):
    name = "load-cell"
    channels = {"thrust": "N", "torque": "N m"}

    def __init__(self, model, vehicle):
        super().__init__(model, vehicle)
        self._z = self._require(model, "load_cell_z").start
        self._yaw = self._require(model, "load_cell_yaw").start
        self._tare_N = LOAD_CELL_MASS_KG * -float(model.opt.gravity[2])

    def read(self, x) -> np.ndarray:
        x = np.asarray(x)
        out = np.empty(x.shape[:-1] + (2,))
        out[..., 0] = LOAD_CELL_K[0] * x[..., self._z] + self._tare_N
        out[..., 1] = LOAD_CELL_K[1] * x[..., self._yaw]
        return out


__all__ = ["LoadCell"]
