"""Sensors: one file per sensor, each turning MuJoCo data into flight-software readings (:mod:`.base`).

:data:`SENSORS` maps each sensor's name to its class: a new sensor is one new file plus one entry here
(tests/test_sensors.py walks the table against the MuJoCo state each sensor measures). :data:`IMU` is the order in
which the flight computer's IMU channels are sampled and draw their noise.
"""

from rotorlab.sim.sensors.base import Sensor, SensorSuite, sensor_slice
from rotorlab.sim.sensors.imu_accelerometer import ImuAccelerometer
from rotorlab.sim.sensors.imu_attitude import ImuAttitude
from rotorlab.sim.sensors.imu_gyro import ImuGyro
from rotorlab.sim.sensors.load_cell import LoadCell
from rotorlab.sim.sensors.tachometer import Tachometer

#: sensor name -> class
SENSORS = {cls.name: cls for cls in (ImuGyro, ImuAttitude, ImuAccelerometer, LoadCell, Tachometer)}
#: the IMU's sensors in sampling (and noise-draw) order
IMU = (ImuGyro, ImuAttitude, ImuAccelerometer)


def imu_suite(model, vehicle) -> SensorSuite | None:
    """The IMU of a model (None on a model without one, e.g. the thrust stand)."""
    try:
        return SensorSuite([cls(model, vehicle) for cls in IMU])
    except LookupError:
        return None


__all__ = ["SENSORS", "IMU", "Sensor", "SensorSuite", "imu_suite", "sensor_slice", "ImuGyro", "ImuAttitude",
           "ImuAccelerometer", "LoadCell", "Tachometer"]
