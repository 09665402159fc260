"""Speed of the identification library on the published problem size (N = 7000 samples at 50 Hz).

Prints measured times and the ratio to the targets: MOESP and PBSID < 30 ms each, nu-gap < 3 ms,
1000 PBSID bootstrap replications < 20 s on 2 cores.

    python benchmarks/bench_ident.py [--n-boot 1000] [--jobs 2]

One BLAS thread per process (set below before numpy loads): the problems are small, and on a shared
2-core machine OpenBLAS threads spin against each other and against the bootstrap worker processes.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import functools  # noqa: E402
import resource
import time  # noqa: E402
import timeit  # noqa: E402

import control as ct  # noqa: E402
import numpy as np  # noqa: E402

from rotorlab.excitation import campaign  # noqa: E402
from rotorlab.ident import IdentifiedModel, bootstrap, moesp, nugap, pbsid  # noqa: E402
from rotorlab.lti import c2d_zoh  # noqa: E402
from rotorlab.vehicles import load_vehicle  # noqa: E402

DT = 0.02
PUBLISHED = load_vehicle("anteos-p2a2").published  # ref. 000 PBSID models, read from the vehicle spec
TESTBED = ct.tf(PUBLISHED["testbed"].num, PUBLISHED["testbed"].den)
FLIGHT = ct.tf(PUBLISHED["flight"].num, PUBLISHED["flight"].den)


def best_ms(fn, repeat=7, number=3):
    """(wall ms, CPU ms) best of ``repeat``: on a shared machine the CPU time shows the cost undiluted
    by other processes' load."""
    wall = min(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e3
    cpu = min(timeit.repeat(fn, number=number, repeat=repeat, timer=time.process_time)) / number * 1e3
    return wall, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n-boot", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()

    truth = IdentifiedModel(c2d_zoh(TESTBED, DT), delay=3)
    segs = [((0.05, 0.1), 7.0, 40.0), ((0.1, 0.2), 9.0, 40.0), ((0.2, 0.4), 11.0, 60.0)]
    u, _ = campaign(segs, DT, seed=0)
    y0 = truth.simulate(u)[:, 0]
    y = y0 + 0.05 * y0.std() * np.random.default_rng(1).standard_normal(len(u))
    u, y = u[:7000], y[:7000]

    rows = []
    t = best_ms(lambda: moesp(u, y, order=4, horizon=40, dt=DT, delay=3))
    rows.append(("MOESP n=4 s=40, N=7000", t, 30.0, "ms"))
    t = best_ms(lambda: moesp(u, y, order=4, horizon=40, dt=DT, delay=3, noise_model=False))
    rows.append(("MOESP n=4 s=40, no noise model", t, 30.0, "ms"))
    t = best_ms(lambda: pbsid(u, y, order=5, past=11, future=7, dt=DT, delay=3))
    rows.append(("PBSID n=5 p/f=11/7, N=7000", t, 30.0, "ms"))
    S1, S2 = ct.ss(TESTBED), ct.ss(FLIGHT)
    t = best_ms(lambda: nugap(S1, S2), number=20)
    rows.append((f"nu-gap P2-A2 test-bed vs flight ({nugap(S1, S2):.4f})", t, 3.0, "ms"))

    ident = functools.partial(pbsid, order=5, past=11, future=7, delay=3, dt=DT)

    ru0 = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    t0 = time.perf_counter()
    res = bootstrap(u, y, ident, n_boot=args.n_boot, seed=0, n_jobs=args.jobs, progress=False)
    wall_b = time.perf_counter() - t0
    ru1 = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    cpu_b = sum(b.ru_utime + b.ru_stime - a.ru_utime - a.ru_stime for a, b in zip(ru0, ru1))
    # with the work spread over the workers, the CPU time divided by the jobs is the wall time on idle cores
    tb = (wall_b, cpu_b / args.jobs)
    assert len(res.models) == args.n_boot
    target_b = 20.0 * args.n_boot / 1000
    rows.append((f"bootstrap {args.n_boot} x PBSID, {args.jobs} jobs", tb, target_b, "s"))

    print(f"cpus available: {len(os.sched_getaffinity(0))}, load average {os.getloadavg()[0]:.1f}")
    print(f"{'':48s} {'wall':>9s}    {'cpu':>9s}   (bootstrap: cpu / jobs)")
    for name, (wall, cpu), target, unit in rows:
        print(f"{name:48s} {wall:9.2f} {unit} {cpu:9.2f} {unit}   target {target:6.1f} {unit}   "
              f"ratio wall {wall / target:5.2f}, cpu {cpu / target:5.2f}")


if __name__ == "__main__":
    main()
