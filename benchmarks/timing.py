"""Timing helper the benchmark scripts share (imported as a sibling module: the scripts run as
``python benchmarks/NAME.py``, which puts this folder on the import path)."""

import os
import time

import numpy as np


def best_wall_s(fn, repeat: int = 1):
    """Best wall time of ``repeat`` calls of ``fn`` (s) and the last call's result: the minimum is the run the
    shared machine disturbed least."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def raw_step_s(vehicle: str, duration_s: float, sensors: bool = True) -> float:
    """CPU seconds of ``duration_s`` of bare ``mj_step`` on ``vehicle``'s free-flight model from its hover
    keyframe (no flight software, no Python between steps): the baseline the per-tick ratios divide by."""
    # imported here: the identification and tuning benchmarks use this module without MuJoCo or the simulator
    import mujoco

    from rotorlab.sim.simulator import Simulator

    sim = Simulator("free-flight", vehicle, sensor_noise=False)
    m, d = sim.model, sim.data
    if not sensors:
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    nstep = int(round(duration_s / m.opt.timestep))
    t0 = time.process_time()
    mujoco.mj_step(m, d, nstep=nstep)
    dt = time.process_time() - t0
    # held at the hover trim it stays airborne: no contacts that would make the raw steps dearer
    assert d.qpos[2] > 1.0, f"the raw run reached the floor (z = {d.qpos[2]:.2f} m)"
    return dt


class Clock:
    """Wall and CPU seconds of a block (CPU includes worker processes that have exited)."""

    def __enter__(self):
        self.w, t = time.perf_counter(), os.times()
        self.c = t.user + t.system + t.children_user + t.children_system
        return self

    def __exit__(self, *exc):
        t = os.times()
        self.wall = time.perf_counter() - self.w
        self.cpu = t.user + t.system + t.children_user + t.children_system - self.c

    def __str__(self):
        return f"{self.wall:6.2f} s wall, {self.cpu:6.2f} s CPU"
