"""IMU attitude (the flight computer's attitude estimate): aerospace ``phi, theta, psi`` (deg) of the IMU site,
with white noise (``[imu] angle_noise_deg``). MuJoCo's ``framequat`` sensor gives the site orientation."""

from __future__ import annotations

import numpy as np

from rotorlab.sim.frames import euler_deg, euler_deg_from_quat, euler_deg_from_quats
from rotorlab.sim.sensors.base import Sensor


class ImuAttitude(Sensor):
    name = "imu-attitude"
    channels = {"phi": "deg", "theta": "deg", "psi": "deg"}

    def __init__(self, model, vehicle):
        super().__init__(model, vehicle)
        self.slice = self._require(model, "imu_quat")
        self.noise_std = np.full(3, vehicle.imu.angle_noise_deg)

    def read(self, x) -> np.ndarray:
        q = x[..., self.slice]
        # one simulation: scalar math on four floats is several times cheaper than numpy on a 4-vector
        return euler_deg_from_quat(q) if q.ndim == 1 else euler_deg_from_quats(q)

    def read_floats(self, x: list) -> tuple:
        return euler_deg(*x[self.slice])


__all__ = ["ImuAttitude"]
