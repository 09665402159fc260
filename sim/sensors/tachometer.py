"""Tachometer: rotor speed of each rotor, rad/s.

Variable RPM: the motor actuator's state is Omega^2 ((rad/s)^2, ``rotorlab.vehicles.build``), so the reading is
its square root. Variable pitch: the rotors turn at the vehicle's fixed ``rotor_speed_rad_s``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from rotorlab.scenes import PREFIX
from rotorlab.sim.sensors.base import Sensor


class Tachometer(Sensor):
    name = "tachometer"
    field = "act"

    def __init__(self, model, vehicle):
        ids = []
        for i in range(1, vehicle.n_rotors + 1):
            a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{PREFIX}thrust{i}")
            if a >= 0:
                ids.append(a)
        if not ids:
            raise LookupError("the model has no rotor thrust actuators for the tachometer")
        # per instance: the thrust stand carries one rotor, a vehicle four
        self.channels = {f"omega{i + 1}": "rad/s" for i in range(len(ids))}
        super().__init__(model, vehicle)
        self._variable_rpm = vehicle.kind == "variable-rpm"
        self._adr = np.asarray(model.actuator_actadr[ids])
        self._fixed = np.full(len(ids), vehicle.rotor.rotor_speed_rad_s)
        if self._variable_rpm and np.any(self._adr < 0):
            raise LookupError("variable-RPM thrust actuators without a motor state")

    def read(self, x) -> np.ndarray:
        x = np.asarray(x)
        if self._variable_rpm:
            return np.sqrt(np.maximum(x[..., self._adr], 0.0))
        return np.broadcast_to(self._fixed, x.shape[:-1] + self._fixed.shape).copy()


__all__ = ["Tachometer"]
