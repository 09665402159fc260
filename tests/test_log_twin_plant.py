"""The log pipeline's twin plant (rotorlab.pipeline.stages.log_calibrate.twin_plant) against the twin's own
linearisation with its rotors' delays (sim/linearize.py, delay=True): on a plus frame each tilt axis is driven by
one rotor pair only, with that pair's delay (tuhh-quad: roll 24 ms, pitch 28 ms), not the mean of all rotors."""

import math

import numpy as np
import pytest

from rotorlab import lti
from rotorlab.pipeline.stages.log_calibrate import twin_plant
from rotorlab.sim.control.autopilot import TORQUE_TO_PCT
from rotorlab.sim.linearize import linearize
from rotorlab.vehicles import load_vehicle
from rotorlab.vehicles.fit_axes import twin_scene

W_RAD_S = np.array([3.0, 10.0, 30.0])


@pytest.mark.parametrize("axis", ["roll", "pitch"])
def test_twin_plant_has_the_delay_of_the_rotors_that_drive_the_axis(axis):
    v = load_vehicle("tuhh-quad")
    assert v.frame == "quad-plus" and len(set(v.rotor.delay_s)) == 2
    dt_s = 0.001  # the physics step: the true linearisation's own sample time
    truth = linearize(twin_scene(v, "gimbal"), v, axis, f"gyro_{axis}", delay=True)
    G = twin_plant(v, axis, dt_s)
    ratio = lti.freqresp(G, W_RAD_S)[:, 0, 0] / (lti.freqresp(truth, W_RAD_S)[:, 0, 0] * TORQUE_TO_PCT * math.pi / 180)
    # the mean of all four rotors' delays would be 2 ms off: 3.4 deg at 30 rad/s
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 0.2
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 0.05
