"""Timings of the robustness tools: Monte Carlo (1000 samples) and margins of a 14th-order discrete loop.

Run: ``python benchmarks/bench_robust.py``. Prints measured wall times and ratios; no assertions.
Single-threaded BLAS is requested before NumPy loads: every matrix here is below 20x20 and a threaded
OpenBLAS spends more time waking threads than computing (10-100x slower on a busy 2-core machine).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import functools  # noqa: E402

import control as ct  # noqa: E402
import numpy as np  # noqa: E402
from timing import best_wall_s  # noqa: E402

from rotorlab import lti  # noqa: E402
from rotorlab.tune.margins import margins  # noqa: E402
from rotorlab.tune.montecarlo import montecarlo, single_loop  # noqa: E402
from rotorlab.tune.robust import control_sensitivity, fit_wdelta, h_lim  # noqa: E402
from rotorlab.vehicles import load_vehicle  # noqa: E402

DT = 0.02
P2A2 = load_vehicle("anteos-p2a2").published["testbed"]  # ref. 000 PBSID test-bed rate model


def p2a2_rate_loop():
    G = lti.with_io_delay(lti.c2d_zoh(ct.tf(P2A2.num, P2A2.den), DT), 3 * DT)
    return G, lti.as_ss(lti.pid_tf(0.257, 0.643, 0.0231, 0.0225, DT))


def fourteenth_order_loop():
    """P2-A2 cascade opened at the angle: plant (2) + 3-sample delay (3) + inner PID (2) + 2nd-order rate
    anti-aliasing filter (2) + 2nd-order notch (2), closed; outer PD (1), angle integrator (1), one sample of
    computation delay (1): 14 states."""
    G, C = p2a2_rate_loop()
    aa = lti.c2d_zoh(ct.tf([60.0 ** 2], [1, 2 * 0.7 * 60, 60.0 ** 2]), DT)
    notch = lti.c2d_zoh(ct.tf([1, 0.2 * 40, 40 ** 2], [1, 1.2 * 40, 40 ** 2]), DT)
    inner = ct.feedback(ct.series(C, G), ct.series(aa, notch))
    pd = lti.as_ss(lti.pid_tf(5.4631, 0.0, 0.9376, 0.0380, DT))
    integ = ct.ss([[1.0]], [[DT]], [[1.0]], [[0.0]], DT)
    L = ct.series(lti.delay_ss(1, DT), pd, inner, integ)
    return lti.as_ss(L)


def main():
    G, C = p2a2_rate_loop()
    rng = np.random.default_rng(0)
    (k, kz), (_, a1, a0) = P2A2.num, P2A2.den
    reps = [lti.with_io_delay(lti.c2d_zoh(ct.tf([k * (1 + 0.05 * rng.standard_normal()), kz],
                                               [1, a1 * (1 + 0.05 * rng.standard_normal()), a0]), DT), 3 * DT)
            for _ in range(100)]
    w = np.geomspace(0.1, 0.9 * np.pi / DT, 120)
    t_fit, W = best_wall_s(lambda: fit_wdelta(G, reps, w))
    h = h_lim(W, control_sensitivity(G, C))
    print(f"fit_wdelta (100 replicas, 120 frequencies): {t_fit:.2f} s; h_lim = {h:.4f}")

    builder = functools.partial(single_loop, C=C)
    t1, r1 = best_wall_s(lambda: montecarlo(G, W, builder, h, n=1000, seed=0, progress=False))
    t2, r2 = best_wall_s(lambda: montecarlo(G, W, builder, h, n=1000, seed=0, n_jobs=2, progress=False))
    same = np.array_equal(r1.setpoint, r2.setpoint, equal_nan=True)
    print(f"montecarlo 1000 samples, {r1.t.size} steps: n_jobs=1 {t1:.2f} s ({1e3 * t1 / 1000:.2f} ms/sample), "
          f"n_jobs=2 {t2:.2f} s (speed-up {t1 / t2:.2f}x), identical results: {same}, "
          f"unstable fraction {r1.fraction_unstable:.3f}")

    L = fourteenth_order_loop()
    assert L.nstates == 14
    t_m, m = best_wall_s(lambda: margins(L), repeat=5)
    t_ct, ref = best_wall_s(lambda: ct.stability_margins(L, method="frd"), repeat=5)
    print(f"margins of a {L.nstates}th-order discrete loop: {1e3 * t_m:.1f} ms "
          f"(python-control stability_margins(method='frd') {1e3 * t_ct:.1f} ms, ratio {t_m / t_ct:.2f}); "
          f"GM {m.gm_db:.2f} dB @ {m.w_pc_rad_s:.2f} rad/s, PM {m.pm_deg:.2f} deg @ {m.w_gc_rad_s:.2f} rad/s, "
          f"disk alpha {m.disk_alpha:.3f}; python-control: GM {20 * np.log10(ref[0]):.2f} dB, PM {ref[1]:.2f} deg")


if __name__ == "__main__":
    main()
