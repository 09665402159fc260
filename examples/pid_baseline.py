"""
The PID baseline on every Gymnasium env
=======================================

Score the vehicle's standard cascade gains on the rotorlab Gymnasium envs: the bar a learned policy has to beat.
Run: ``python examples/pid_baseline.py [--episodes N]`` (default 2). Prints the mean and spread of the episode
return of the PID baseline and of a zero-action policy (the floor) on each env, over seeds 0..N-1.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import rotorlab  # noqa: F401  (registers the envs)
from rotorlab.sim.env_baselines import HoverPIDPolicy, RigPIDPolicy, episode_return


class HoldPolicy:
    """Constant action: zero axis command (and the hover collective in flight)."""

    def __init__(self, env):
        e = env.unwrapped
        phys = np.zeros(env.action_space.shape)
        if e.scene_name == "free-flight":
            phys[0] = e.vehicle.hover_collective_pct
        self.a = e.normalize_action(phys)

    def reset(self):
        pass

    def __call__(self, obs):
        return self.a


def main() -> None:
    ap = argparse.ArgumentParser(description="Score the standard PID gains on every rotorlab Gymnasium env.")
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args()
    cases = (("rotorlab/PitchRig-v0", RigPIDPolicy), ("rotorlab/RollRig-v0", RigPIDPolicy),
             ("rotorlab/Hover-v0", HoverPIDPolicy))
    for env_id, pid in cases:
        env = gym.make(env_id)
        for name, policy in (("PID (standard gains)", pid(env)), ("hold (zero action)", HoldPolicy(env))):
            rets, crashes = [], 0
            for seed in tqdm(range(args.episodes), desc=f"{env_id} {name}", leave=False, disable=args.no_progress):
                ret, _, terminated = episode_return(env, policy, seed)
                rets.append(ret)
                crashes += terminated
            print(f"{env_id:22s} {name:22s} mean return {np.mean(rets):9.2f} +- {np.std(rets):7.2f} "
                  f"over {args.episodes} episodes ({crashes} terminated early)")
        env.close()


if __name__ == "__main__":
    main()
