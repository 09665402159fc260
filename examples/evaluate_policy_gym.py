"""
Evaluate a policy on a Gymnasium env
====================================

``import rotorlab`` registers ``rotorlab/PitchRig-v0``, ``rotorlab/RollRig-v0`` and ``rotorlab/Hover-v0``. Actions
are normalised to [-1, 1] (what stable-baselines3 and most RL libraries expect) and scaled to physical units by the
env. This example scores three policies on the pitch rig's set-point tracking task: a zero action (the floor), a
hand-written proportional-derivative policy, and the published PID cascade (the bar a learned policy has to beat).
A trained agent is evaluated the same way: any callable from observation to action.
"""

import gymnasium as gym
import numpy as np

import rotorlab  # noqa: F401  (registers the envs)
from rotorlab.sim.env_baselines import RigPIDPolicy, episode_return

EPISODES = 2  # seeds 0 and 1; use more for a tighter estimate

env = gym.make("rotorlab/PitchRig-v0", episode_s=4.0, max_episode_steps=200)
print("observation:", env.observation_space, "\naction:", env.action_space, env.unwrapped.action_units)


class PDPolicy:
    """``u = kp (theta_ref - theta) - kd q`` in %, normalised to the env's action range."""

    def __init__(self, env, kp=1.5, kd=0.25):
        self.env, self.kp, self.kd = env.unwrapped, kp, kd

    def reset(self):
        pass

    def __call__(self, obs):
        theta, q, theta_ref = obs[0], obs[1], obs[2]  # deg, deg/s, deg (the env's observation table)
        return self.env.normalize_action([self.kp * (theta_ref - theta) - self.kd * q])


class ZeroPolicy:
    def reset(self):
        pass

    def __call__(self, obs):
        return np.zeros(1)


# %%
# ``episode_return`` runs one seeded episode and returns (return, steps, terminated early).
scores = {}
for name, policy in (("zero", ZeroPolicy()), ("PD", PDPolicy(env)), ("published PID", RigPIDPolicy(env))):
    returns = [episode_return(env, policy, seed=s)[0] for s in range(EPISODES)]
    scores[name] = float(np.mean(returns))
    print(f"{name:14s} mean return {scores[name]:9.3f}")
env.close()
assert scores["published PID"] > scores["zero"]
