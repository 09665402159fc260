"""
Add a sensor
============

A sensor is one class following :class:`rotorlab.sim.sensors.Sensor`: it finds its data in the compiled MuJoCo
model (raising :class:`LookupError` where the model lacks it, so the simulator skips it there) and turns one MjData
field into readings in flight-software units. This one is a quantised optical encoder on the test-bed's bearing,
reading the rig angle in degrees, as a real test-bed would carry besides the vehicle's IMU.

Registered in :data:`rotorlab.sim.sensors.SENSORS`, every simulator whose model has a rig bearing carries it. To
ship it with rotorlab, put the class in its own file under ``sim/sensors/`` and add it to that table (the test
suite walks the table against the MuJoCo state each sensor measures).
"""


import mujoco
import numpy as np

from rotorlab.scenes import RIG_AXES
from rotorlab.sim.sensors import SENSORS, Sensor
from rotorlab.sim.simulator import Simulator


class RigEncoder(Sensor):
    """Rig angle from the bearing's hinge joint, deg, quantised to ``COUNTS`` per revolution."""

    name = "rig-encoder"
    channels = {"rig_angle": "deg"}
    field = "qpos"  # MuJoCo's joint positions: the hinge angle, rad
    COUNTS = 4096

    def __init__(self, model, vehicle):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rig_bearing")
        if jid < 0:
            raise LookupError("the model has no rig bearing")  # free flight, the thrust stand
        super().__init__(model, vehicle)
        self._adr = int(model.jnt_qposadr[jid])
        # the hinge turns about the joint axis; the rig's angle is positive about the rig axis (nose up)
        axis, rig = model.jnt_axis[jid], next(a for _, a in RIG_AXES.values() if np.allclose(np.abs(a), np.abs(
            model.jnt_axis[jid])))
        self._sign = float(np.dot(axis, rig))
        self._step_deg = 360.0 / self.COUNTS

    def read(self, x) -> np.ndarray:
        angle_deg = np.degrees(np.asarray(x)[..., self._adr:self._adr + 1]) * self._sign
        return np.round(angle_deg / self._step_deg) * self._step_deg


SENSORS[RigEncoder.name] = RigEncoder

# %%
# Fly the pitch rig open loop for one second with a small nose-up command and compare the encoder with the true
# airframe pitch angle and the IMU's attitude channel.
sim = Simulator("pitch-rig", "anteos-p2a2", seed=0, sensor_noise=False)
encoder = sim.sensors["rig-encoder"]
for _ in range(int(round(1.0 / sim.control_dt_s))):
    sim.set_commands([sim.vehicle.hover_collective_pct, 0.0, 2.0, 0.0])
    sim.tick()
reading = float(encoder.read(sim.data.qpos)[0])
true_theta = sim.true_attitude_deg()[1]
print(f"encoder {reading:.3f} deg, true pitch {true_theta:.3f} deg, IMU {sim.measure()['theta']:.3f} deg")
assert abs(reading - true_theta) <= encoder._step_deg
assert "rig-encoder" not in Simulator("free-flight", "anteos-p2a2").sensors  # no bearing in free flight
del SENSORS[RigEncoder.name]
