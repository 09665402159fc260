"""Env step throughput, single and vectorised (sync), against raw ``mj_step`` of the same compiled model.

The ratio is (time of the env's physics steps done as bare ``mj_step(m, d, nstep)``) / (time of one env step):
1.0 means the env adds nothing to the physics. Target: >= 0.5 for a single env.

Times are process CPU time (``time.process_time``): on a shared machine wall-clock time mostly measures the other
processes; best of 3 interleaved rounds.

Run: ``python benchmarks/bench_envs.py [--steps N]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import gymnasium as gym
import mujoco
import numpy as np

import rotorlab  # noqa: F401  (registers the envs)
from rotorlab.sim.rerun_log import record_run
from rotorlab.sim.runner import run_scenario


def _raw_us_per_agent_step(env, n: int) -> float:
    sim = env.unwrapped.sim
    m, d = sim.model, mujoco.MjData(sim.model)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.ctrl[:] = sim.data.ctrl
    t0 = time.process_time()
    for _ in range(n):
        mujoco.mj_step(m, d, nstep=sim.n_substeps)
    return (time.process_time() - t0) / n * 1e6


def _env_us_per_step(env, n: int) -> float:
    env.reset(seed=0)
    phys = np.zeros(env.action_space.shape)
    if env_id_is_hover(env):
        phys[0] = env.unwrapped.vehicle.hover_collective_pct
    a = env.unwrapped.normalize_action(phys)  # actions are normalised to [-1, 1]
    t0 = time.process_time()
    for _ in range(n):
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return (time.process_time() - t0) / n * 1e6


def env_id_is_hover(env) -> bool:
    return env.unwrapped.scene_name == "free-flight"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--num-envs", type=int, default=4)
    args = ap.parse_args()
    n = args.steps
    print(f"{'env (CPU us per agent step)':32s} {'gym.make':>10s} {'raw mj_step':>12s} {'ratio':>6s} {'unwrapped':>10s} {'ratio':>6s}")
    for env_id, kw in (("rotorlab/PitchRig-v0", {}), ("rotorlab/PitchRig-v0", {"control": "inner_loop"}),
                       ("rotorlab/Hover-v0", {}), ("rotorlab/Hover-v0", {"control": "attitude"})):
        env = gym.make(env_id, **kw)
        # best of 3 interleaved rounds: the shared machine's load shifts between measurements
        wrapped, bare, raw = (min(x) for x in zip(*[
            (_env_us_per_step(env, n), _env_us_per_step(env.unwrapped, n), _raw_us_per_agent_step(env, n))
            for _ in range(3)]))
        label = env_id + (f" {kw['control']}" if kw else "")
        print(f"{label:32s} {wrapped:10.1f} {raw:12.1f} {raw / wrapped:6.2f} {bare:10.1f} {raw / bare:6.2f}")
        env.close()
    for env_id in ("rotorlab/PitchRig-v0", "rotorlab/Hover-v0"):
        venv = gym.make_vec(env_id, num_envs=args.num_envs, vectorization_mode="sync")
        venv.reset(seed=0)
        a = np.zeros(venv.action_space.shape, dtype=np.float32)
        if env_id.endswith("Hover-v0"):
            a[:, 0] = 0.6  # collective 80 % on the normalised scale (50 + 50 a)
        t0 = time.process_time()
        for _ in range(n // args.num_envs):
            venv.step(a)
        dt = (time.process_time() - t0) / (n // args.num_envs * args.num_envs) * 1e6
        print(f"{env_id} sync x{args.num_envs}: {dt:.1f} us per env step ({1e6 / dt:.0f} env steps/s, "
              f"{1e6 / dt * 0.02:.1f}x real time)")
        venv.close()
    bench_recording()


def bench_recording(duration_s: float = 10.0, rounds: int = 9) -> None:
    """Cost of ``run --rerun``: pose recording in the run loop and the column-wise write, vs the run itself.
    Best of 9 interleaved rounds: a 10 s run on the rig is about 0.12 s of CPU, and the best of 3 moved by more
    than the overhead measured from one call to the next."""
    # warm caches, imports and the allocator: one whole run of each kind (the first call's runs with poses were
    # all slower by about a quarter without it)
    run_scenario("rest", duration_s=duration_s)
    run_scenario("rest", duration_s=duration_s, record_poses=True)

    def timed(**kw):
        t0 = time.process_time()
        res = run_scenario("rest", duration_s=duration_s, **kw)
        return time.process_time() - t0, res

    plain = posed = write = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(rounds):  # best of interleaved rounds
            plain = min(plain, timed()[0])
            dt, res = timed(record_poses=True)
            posed = min(posed, dt)
            t0 = time.process_time()
            record_run(res, f"{tmp}/run{i}.rrd")
            write = min(write, time.process_time() - t0)
    print(f"rest {duration_s:g} s on the pitch rig: run {plain:.3f} s, with poses {posed:.3f} s "
          f"(+{(posed - plain) / plain:.0%}), record_run {write:.3f} s ({write / plain:.0%} of the run); "
          f"total recording overhead {(posed - plain + write) / plain:.0%}")


if __name__ == "__main__":
    main()
