"""
Fly a custom disturbance
========================

A disturbance is one class following :class:`rotorlab.sim.disturbances.base.Disturbance`: it acts on the
simulator at every control tick (here a moment on the airframe through MuJoCo's ``xfrc_applied``) and logs its
ground truth. This one is a sinusoidal pitching moment, as a rotor-wake interaction at a fixed frequency might
make. The standard cascade flies the pitch rig through it, in the Gymnasium env, with the published PID.

To ship a disturbance with rotorlab, put the class in its own file under ``sim/disturbances/`` and add it to
:data:`rotorlab.sim.disturbances.DISTURBANCES` (the test suite walks that table).
"""

import math

import gymnasium as gym
import mujoco
import numpy as np

import rotorlab  # noqa: F401  (registers the envs)
from rotorlab.scenes import PREFIX, RIG_AXES
from rotorlab.sim.disturbances import Disturbance
from rotorlab.sim.env_baselines import RigPIDPolicy


class SineMoment(Disturbance):
    """A moment ``amplitude_Nm * sin(2 pi f t)`` about the rig's axis (positive raises the rig angle)."""

    name = "sine-moment"
    scenes = tuple(RIG_AXES)  # the rigs: the moment acts about the rig's one free axis
    columns = {"sine_moment": "N m"}
    stage = mujoco.mjtStage.mjSTAGE_ACC  # it writes xfrc_applied, an input of the acceleration stage

    def __init__(self, amplitude_Nm: float, frequency_hz: float):
        self.amplitude_Nm, self.frequency_hz = float(amplitude_Nm), float(frequency_hz)

    def reset(self, sim, rng) -> None:
        self._axis = np.asarray(RIG_AXES[sim.scene.name][1], dtype=float)
        self._body = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, f"{PREFIX}airframe")

    def moment(self, t: float) -> float:
        return self.amplitude_Nm * math.sin(2 * math.pi * self.frequency_hz * t)

    def update(self, sim, t: float) -> None:
        sim.data.xfrc_applied[self._body, 3:6] += self.moment(t) * self._axis

    def values(self, sim) -> dict:
        return {"sine_moment": self.moment(sim.time)}


# %%
# Regulation on the pitch rig (set-point 0) with and without the disturbance, over a 5 s episode.
def fly(disturbances):
    env = gym.make("rotorlab/PitchRig-v0", task="regulation", episode_s=5.0, sensor_noise=False,
                   disturbances=disturbances, max_episode_steps=250)
    policy = RigPIDPolicy(env)
    obs, _ = env.reset(seed=0)
    policy.reset()
    angles = []
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        angles.append(obs[0])
        done = terminated or truncated
    env.close()
    return np.asarray(angles)


calm = fly([])
disturbed = fly([SineMoment(amplitude_Nm=0.3, frequency_hz=1.0)])
print(f"pitch angle RMS: calm {np.sqrt(np.mean(calm ** 2)):.3f} deg, "
      f"with the 1 Hz moment {np.sqrt(np.mean(disturbed ** 2)):.3f} deg")
assert np.sqrt(np.mean(disturbed ** 2)) > 2 * np.sqrt(np.mean(calm ** 2))
