"""Grey-box identification timings: OE fits (open and closed loop), H-inf matching, and the fits' simulation
(impulse response and convolution) against scipy's dlsim. Prints measured times and ratios; run ``python benchmarks/bench_greybox.py``."""

from __future__ import annotations

import numpy as np
import scipy.signal as sig
from timing import best_wall_s

from rotorlab.ident.greybox import _lsim, oe_fit, oe_fit_closed_loop, simulate_closed_loop, simulate_greybox
from rotorlab.ident.hinf_match import hinf_match
from rotorlab.ident.structures import pitch_structure, rigid_rig_structure, tuhh_axis_structure
from rotorlab.lti import as_ss, c2d_zoh, pid_tf


def main():
    rng = np.random.default_rng(0)
    dt, N = 0.02, 3000
    u = np.repeat(rng.choice([-9.0, 9.0], N // 5), 5)
    m = pitch_structure()
    sysd = m.discretize(dt)
    t_lf, y1 = best_wall_s(lambda: _lsim(sysd, u[:, None]), 20)
    A, B, C, D = (np.asarray(M) for M in (sysd.A, sysd.B, sysd.C, sysd.D))
    t_dl, (_, y2, _) = best_wall_s(lambda: sig.dlsim((A, B, C, D, dt), u), 5)
    print(f"simulate {N} samples, {sysd.nstates} states: _lsim {t_lf * 1e3:.2f} ms, dlsim {t_dl * 1e3:.2f} ms "
          f"(x{t_dl / t_lf:.0f}); max difference {np.max(np.abs(y1[:, 0] - np.ravel(y2))):.1e}")

    y = simulate_greybox(m, u, dt)[:, 0]
    y += 0.05 * y.std() * rng.standard_normal(N)
    t_oe, res = best_wall_s(lambda: oe_fit(m, u, y, dt, theta0={n: 1.3 * m.values()[n] for n in m.free}), 1)
    print(f"oe_fit pitch structure (5 params, N={N}): {t_oe:.2f} s, {res.nfev} evaluations, VAF {res.fit_vaf[0]:.2f} %")

    dtc, Nc = 0.005, 3000
    tm = tuhh_axis_structure("pitch")
    K = as_ss(pid_tf(0.12, 0.0, 0.025, 0.01, dtc))
    r = np.repeat(rng.choice([-0.2, 0.2], Nc // 40), 40)
    yc = simulate_closed_loop(tm, K, r, dtc)[:, 0]
    yc += 0.03 * yc.std() * rng.standard_normal(Nc)
    t_cl, rc = best_wall_s(lambda: oe_fit_closed_loop(tm, K, r, yc, dtc, theta0=dict(J=0.023, p=22.0, Td=0.024)), 1)
    print(f"oe_fit_closed_loop TUHH pitch (3 params, N={Nc}): {t_cl:.2f} s, {rc.nfev} evaluations")

    rr = rigid_rig_structure()
    bb = c2d_zoh(rr.ss(), dt)
    t_h, rh = best_wall_s(lambda: hinf_match(bb, rr, theta0={n: 1.3 * rr.values()[n] for n in rr.free}, restarts=0), 1)
    print(f"hinf_match rigid-rig (4 params, 15th-order weight): {t_h:.2f} s, norm {rh.norm:.2e}")
    p = pitch_structure()
    t_h2, rh2 = best_wall_s(lambda: hinf_match(c2d_zoh(p.ss(), dt), p, theta0={n: 1.3 * p.values()[n] for n in p.free},
                                               restarts=0), 1)
    print(f"hinf_match pitch structure (5 params): {t_h2:.2f} s, norm {rh2.norm:.2e}")


if __name__ == "__main__":
    main()
