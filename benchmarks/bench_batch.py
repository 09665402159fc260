"""Batched closed-loop validation vs bare ``mujoco.batch`` stepping of the same model (issue 6, "Scale").

Acceptance: ``run_batch`` of N x T s closed-loop runs (flight software, IMU noise, logging every tick) reaches at
least 0.8x the throughput of ``mujoco.batch.Batch`` stepping the same model, from the same reset state, for the
same ticks of 20 physics steps with zero control. Throughputs are simulated seconds per wall-clock second (all
simulations together). A second reference holds the hover trim instead of zero control (the rig then stays
level, as in the closed loop, instead of resting on its stop).

The full size is 1000 x 10 s; on a small machine pass ``--n 100`` and read the projection.

    python benchmarks/bench_batch.py --n 100
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
from mujoco.batch import Batch

from rotorlab.sim.batch import run_batch
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator


def bare_batch(n: int, duration_s: float, nthread: int, trim: bool) -> float:
    """Wall time of bare Batch stepping (zero control, or the hover trim held) for the run's ticks."""
    sim = Simulator("pitch-rig", "anteos-p2a2", sensor_noise=False)
    m = sim.model
    row = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, sim.data, row, mujoco.mjtState.mjSTATE_INTEGRATION)
    b = Batch(m, nsim=n, nthread=nthread)
    b.state[:] = row
    if not trim:
        b.ctrl = 0.0
    n_ticks = int(round(duration_s / sim.control_dt_s))
    t0 = time.perf_counter()
    for _ in range(n_ticks):
        b.step(nstep=sim.n_substeps)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="simulations (default 1000)")
    ap.add_argument("--duration", type=float, default=10.0, help="run length, s (default 10)")
    ap.add_argument("--nthread", type=int, default=0, help="batch threads (0: all CPUs)")
    ap.add_argument("--scenario", default="setpoint", help="closed-loop scenario (setpoint or gust)")
    ap.add_argument("--progress", action="store_true", help="tqdm bar over the closed-loop ticks")
    a = ap.parse_args(argv)
    n, T = a.n, a.duration
    sim_s = n * T

    t_zero = bare_batch(n, T, a.nthread, trim=False)
    t0 = time.perf_counter()
    res = run_batch(a.scenario, n=n, duration_s=T, nthread=a.nthread, progress=a.progress)
    t_loop = time.perf_counter() - t0
    t_trim = bare_batch(n, T, a.nthread, trim=True)
    t0 = time.perf_counter()
    table = res.metrics
    t_metrics = time.perf_counter() - t0
    t0 = time.perf_counter()
    run_scenario(a.scenario, duration_s=T)
    t_scalar = time.perf_counter() - t0

    stopped = sum(s is not None for s in res.stopped)
    print(f"{n} x {T:g} s '{a.scenario}' on pitch-rig, {res.info['nthread']} batch threads, "
          f"{n * round(T / res.info['control_dt_s']) * 20:,} physics steps; {stopped} runs stopped early")
    rows = [("bare Batch, zero control", t_zero), ("bare Batch, hover trim held", t_trim),
            ("run_batch closed loop (noise, logging)", t_loop)]
    for name, t in rows:
        print(f"  {name:40s} {t:8.2f} s   {sim_s / t:9.1f} sim-s/s   "
              f"(1000 x 10 s projected: {1e4 / (sim_s / t):7.1f} s)")
    print(f"  {'scalar run_scenario, one run':40s} {t_scalar:8.2f} s   {T / t_scalar:9.1f} sim-s/s")
    print(f"  metrics table ({len(table)} metrics x {n} runs): {t_metrics:.2f} s, not in the closed-loop time")
    r_zero, r_trim = t_zero / t_loop, t_trim / t_loop
    print(f"throughput ratio closed loop / bare zero control: {r_zero:.3f}  (target >= 0.8: "
          f"{'met' if r_zero >= 0.8 else 'NOT met'})")
    print(f"throughput ratio closed loop / bare hover trim:   {r_trim:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
