"""IMU accelerometer: specific force ``ax, ay, az`` (m/s^2, body FRD) at the IMU site, with white noise
(``[imu] accel_noise_mps2``). MuJoCo's ``accelerometer`` sensor is an acceleration-stage sensor: it is current
only after a full forward pass."""

from __future__ import annotations

import numpy as np

from rotorlab.sim.frames import FLU_TO_FRD
from rotorlab.sim.sensors.base import Sensor

_KX, _KY, _KZ = FLU_TO_FRD.tolist()  # unpacked: read_floats runs every tick


class ImuAccelerometer(Sensor):
    name = "imu-accelerometer"
    channels = {"ax": "m/s^2", "ay": "m/s^2", "az": "m/s^2"}
    acceleration_stage = True

    def __init__(self, model, vehicle):
        super().__init__(model, vehicle)
        self.slice = self._require(model, "accel")
        self.noise_std = np.full(3, vehicle.imu.accel_noise_mps2)

    def read(self, x) -> np.ndarray:
        return x[..., self.slice] * FLU_TO_FRD

    def read_floats(self, x: list) -> list:
        a, b, c = x[self.slice]
        return [a * _KX, b * _KY, c * _KZ]


__all__ = ["ImuAccelerometer"]
