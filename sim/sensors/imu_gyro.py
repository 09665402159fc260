"""IMU gyroscope: body rates ``p, q, r`` (deg/s, FRD) of the IMU site, with white noise and a turn-on bias
(``[imu] gyro_noise_dps``, ``gyro_bias_dps`` of the vehicle TOML). MuJoCo's ``gyro`` sensor gives the site's
angular velocity in its own (FLU) frame, rad/s."""

from __future__ import annotations

import numpy as np

from rotorlab.sim.frames import FLU_TO_FRD, RAD2DEG
from rotorlab.sim.sensors.base import Sensor

_SCALE = FLU_TO_FRD * RAD2DEG
_KP, _KQ, _KR = _SCALE.tolist()  # unpacked: read_floats runs every tick


class ImuGyro(Sensor):
    name = "imu-gyro"
    channels = {"p": "deg/s", "q": "deg/s", "r": "deg/s"}

    def __init__(self, model, vehicle):
        super().__init__(model, vehicle)
        self.slice = self._require(model, "gyro")
        self.noise_std = np.full(3, vehicle.imu.gyro_noise_dps)
        self.bias_std = vehicle.imu.gyro_bias_dps

    def read(self, x) -> np.ndarray:
        return x[..., self.slice] * _SCALE

    def read_floats(self, x: list) -> list:
        p, q, r = x[self.slice]
        return [p * _KP, q * _KQ, r * _KR]


__all__ = ["ImuGyro"]
