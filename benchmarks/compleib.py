"""Held-out check on published static-output-feedback H-inf problems of COMPleib (F. Leibfritz, "COMPleib:
COnstrained Matrix-optimization Problem library", Univ. Trier, 2004/2006), solved as a user would:
``hinfstruct(P, "static", ny, nu, starts=N)``, every result re-verified independently: the closed loop built
a second way (python-control's ``feedback`` of P with the padded gain), its poles, its norm by ab13dd and as
the maximum of sigma_max over a dense frequency grid.

Data. HE3 and HE4 (8-state helicopter models, 4 inputs, 6 measurements) are transcribed from the Mathematica
export of COMPleib in the NCAlgebra repository (github.com/NCAlgebra/NC, TESTING/NCSDP/COMPleib/MmaCOMPleib/
HE3.m and HE4.m, commit b4bf96d) and checked entry by entry against COMPleib 1.1's own ``COMPleib.m``
(github.com/xi1ngang/Hinf-structured-output-Feedback, COMPlib_r1_1/COMPleib.m, commit 33dce0f); AC15
(supersonic transport at Mach 2.7, 4 states, 2 inputs, 3 measurements) is transcribed from that
``COMPleib.m``. The problem is ``dx = A x + B1 w + B u, z = C1 x + D11 w + D12 u, y = C x + D21 w``
(COMPleib's names). DLR2/DLR3 (40 states, 2 x 2) are loaded there from a binary ``dlr2_3.mat`` that no
source reachable here holds, so they are not run.

Published values (:data:`PUBLISHED`). The only ones found are the baseline values of Table 1 of X. Guo, D.
Keivan, G. Dullerud, P. Seiler, B. Hu, "Complexity of derivative-free policy optimization for structured
H-inf control", NeurIPS 2023, as written in the authors' code (github.com/xi1ngang/Hinf-structured-
output-Feedback, figure3_table1_code.m, commit 7e7a5d1, "Basline values" comment; model_based_methods.m
computes them with HIFOO 3.501 and MATLAB's hinfstruct with 5 random starts on ``COMPleib(name)``): HIFOO
15.2919 (AC15), 4.0066e3 (DLR2), 22.8382 (HE4); hinfstruct 15.2, 4.01e3, 22.8 (three digits). No published
static H-inf value for HE3 was found (the HIFOO and hinfstruct benchmark papers' tables could not be read
from any source reachable here), so HE3 is compared with a long Nelder-Mead run instead.

The full-order ``control.hinfsyn`` value is printed as a lower bound where its rank conditions hold.

Run: ``python benchmarks/compleib.py [--starts 4] [--jobs 2] [--problems HE3 HE4 AC15]``.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import control as ct  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import minimize  # noqa: E402

from rotorlab import lti  # noqa: E402
from rotorlab.executor import get_executor  # noqa: E402
from rotorlab.tune.hinfstruct import closed_loop, hinfstruct  # noqa: E402

HE3 = dict(
    A=[[-0.0046, 0.038, 0.3259, -0.0045, -0.402, -0.073, -9.81, 0],
       [-0.1978, -0.5667, 0.357, -0.0378, -0.2149, 0.5683, 0, 0],
       [0.0039, -0.0029, -0.2947, 0.007, 0.2266, 0.0148, 0, 0],
       [0.0133, -0.0014, -0.4076, -0.0654, -0.4093, 0.2674, 0, 9.81],
       [0.0127, -0.01, -0.8152, -0.0397, -0.821, 0.1442, 0, 0],
       [-0.0285, -0.0232, 0.1064, 0.0709, -0.2786, -0.7396, 0, 0],
       [0, 0, 1, 0, 0, 0, 0, 0],
       [0, 0, 0, 0, 1, 0, 0, 0]],
    B1=[[0.0676], [-1.1151], [0.0062], [-0.017], [-0.0129], [0.139], [0], [0]],
    B=[[0.0676, 0.1221, -0.0001, -0.0016], [-1.1151, 0.1055, 0.0039, 0.0035], [0.0062, -0.0682, 0.001, -0.0035],
       [-0.017, 0.0049, 0.1067, 0.1692], [-0.0129, 0.0106, 0.2227, 0.143], [0.139, 0.0059, 0.0326, -0.407],
       [0, 0, 0, 0], [0, 0, 0, 0]],
    C1=np.vstack([np.eye(8)[[1, 6, 7, 5, 2, 4]], np.zeros((4, 8))]),
    C=np.eye(8)[[1, 6, 7, 5, 2, 4]],
    D11=np.zeros((10, 1)),
    D12=np.vstack([np.zeros((6, 4)), np.eye(4)]),
    D21=[[0], [0.1], [0], [0], [0.05], [0]],
)

HE4 = dict(
    A=[[0, 0, 0, 0.99857378005981, 0.05338427424431, 0, 0, 0],
       [0, 0, 1, -0.0031822193414, 0.0595246553421, 0, 0, 0],
       [0, 0, -11.5704956054688, -2.54463768005371, -0.0636026263237, 0.10678052902222, -0.09491866827011,
        0.00710757449269],
       [0, 0, 0.43935656547546, -1.99818229675293, 0, 0.01665188372135, 0.01846204698086, -0.00118747074157],
       [0, 0, -2.04089546203613, -0.4589991569519, -0.73502779006958, 0.01925575733185, -0.00459562242031,
        0.00212036073208],
       [-32.1036071777344, 0, -0.50335502624512, 2.29785919189453, 0, -0.0212158113718, -0.02116791903973,
        0.01581159234047],
       [0.10216116905212, 32.0578308105469, -2.34721755981445, -0.50361156463623, 0.83494758605957,
        0.02122657001019, -0.0378797352314, 0.00035400385968],
       [-1.91097259521484, 1.71382904052734, -0.00400543212891, -0.05741119384766, 0, 0.01398963481188,
        -0.00090675335377, -0.29051351547241]],
    B1=np.eye(8),
    B=[[0, 0, 0, 0], [0, 0, 0, 0],
       [0.12433505058289, 0.08278584480286, -2.75247764587402, -0.01788876950741],
       [-0.03635892271996, 0.47509527206421, 0.01429074257612, 0],
       [0.30449151992798, 0.01495801657438, -0.49651837348938, -0.20674192905426],
       [0.28773546218872, -0.54450607299805, -0.01637935638428, 0],
       [-0.01907348632812, 0.01636743545532, -0.54453611373901, 0.23484230041504],
       [-4.82063293457031, -0.00038146972656, 0, 0]],
    C1=np.vstack([np.eye(8), np.zeros((4, 8))]),
    C=[[0, 0, 0, 0, 0, 0.0595, 0.05329, -0.9968], [1, 0, 0, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0, 0, 0],
       [0, 0, 0, -0.05348, 1, 0, 0, 0], [0, 0, 1, 0, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0, 0, 0]],
    D11=np.zeros((12, 8)),
    D12=np.vstack([np.zeros((8, 4)), np.eye(4)]),
    D21=np.zeros((6, 8)),
)

AC15 = dict(
    A=[[-0.037, 0.0123, 0.00055, -1], [0, 0, 1, 0], [-6.37, 0, -0.23, 0.0618], [1.25, 0, 0.016, -0.0457]],
    B1=np.eye(4),
    B=[[0.00084, 0.000236], [0, 0], [0.08, 0.804], [-0.0862, -0.0665]],
    C1=np.vstack([np.eye(4), np.zeros((2, 4))]),
    C=[[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
    D11=np.zeros((6, 4)),
    D12=np.vstack([np.zeros((4, 2)), np.eye(2)]),
    D21=np.zeros((3, 4)),
)

PROBLEMS = {"HE3": HE3, "HE4": HE4, "AC15": AC15}

# best published static H-inf values: {problem: ((method, value), ...)}, sources in the module docstring
PUBLISHED = {
    "AC15": (("HIFOO", 15.2919), ("hinfstruct", 15.2)),
    "HE4": (("HIFOO", 22.8382), ("hinfstruct", 22.8)),
    "DLR2": (("HIFOO", 4.0066e3), ("hinfstruct", 4.01e3)),
}


def plant(d):
    """Generalised plant ``[w; u] -> [z; y]`` with D22 = 0 (COMPleib's convention)."""
    A, B1, B, C1, C, D11, D12, D21 = (np.asarray(d[k], float) for k in ("A", "B1", "B", "C1", "C", "D11", "D12",
                                                                          "D21"))
    D = np.block([[D11, D12], [D21, np.zeros((C.shape[0], B.shape[1]))]])
    return ct.ss(A, np.hstack([B1, B]), np.vstack([C1, C]), D), C.shape[0], B.shape[1]


def verify(P, ny, nu, K):
    """(stable, ab13dd norm, grid norm) of the closed loop built independently of the engine: P closed by
    python-control's ``feedback`` with the gain padded to all of P's outputs and inputs."""
    nz, nw = P.noutputs - ny, P.ninputs - nu
    Kpad = np.zeros((P.ninputs, P.noutputs))
    Kpad[nw:, nz:] = K
    CL = ct.feedback(P, ct.ss([], [], [], Kpad), sign=1)[:nz, :nw]
    stable = lti.is_stable(CL)
    g = lti.hinfnorm(CL)[0]
    w = np.logspace(-4, 4, 40000)
    grid = float(np.max(np.linalg.svd(lti.freqresp(CL, w), compute_uv=False)))
    return stable, g, grid


def nelder_mead(P, ny, nu, K, fev):
    """Nelder-Mead on the exact norm (inf when unstable) from K: if it descends, the engine stopped short."""
    def f(k):
        return lti.hinfnorm(closed_loop(P, ny, nu, ct.ss([], [], [], k.reshape(K.shape))))[0]

    r = minimize(f, K.ravel(), method="Nelder-Mead",
                 options={"maxfev": fev, "adaptive": True, "xatol": 1e-10, "fatol": 1e-12})
    return min(float(r.fun), f(K.ravel()))


def hinfsyn_bound(P, ny, nu):
    """Full-order optimum (control.hinfsyn, re-verified by ab13dd), or nan where D12 lacks full column rank or
    D21 full row rank: there SLICOT's sb10ad does not apply (on HE4, D21 = 0, it never returns, which is what
    kept the previous run of this script from finishing)."""
    D = np.asarray(P.D, float)
    nz, nw = P.noutputs - ny, P.ninputs - nu
    if np.linalg.matrix_rank(D[:nz, nw:]) < nu or np.linalg.matrix_rank(D[nz:, :nw]) < ny:
        return np.nan
    _, CLf, _, _ = ct.hinfsyn(P, ny, nu)
    return lti.hinfnorm(CLf)[0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS))
    ap.add_argument("--baseline-fev", type=int, default=6000)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    rows = []
    for name in a.problems:
        P, ny, nu = plant(PROBLEMS[name])
        t = time.perf_counter()
        with get_executor("local" if a.jobs > 1 else "serial", a.jobs) as ex:
            r = hinfstruct(P, "static", ny, nu, starts=a.starts, seed=0, executor=ex)
        wall = time.perf_counter() - t
        K = np.asarray(r.controller.D)
        stable, g, grid = verify(P, ny, nu, K)
        nm = nelder_mead(P, ny, nu, K, a.baseline_fev)
        bound = hinfsyn_bound(P, ny, nu)
        pub = min((v for _, v in PUBLISHED.get(name, ())), default=np.nan)
        gs = np.array(r.starts)
        rows.append((name, P.nstates, K.size, g, stable, grid, nm, bound, pub, int(np.sum(gs <= g * 1.02)), gs.size,
                     np.median(r.start_cpu_s), np.median(r.start_times_s)))
        print(f"{name}: gamma {r.gamma:.6g}; re-verified: ab13dd {g:.6g}, grid max {grid:.6g}, stable {stable}; "
              f"Nelder-Mead from it {nm:.6g}; published {pub:.6g} (gap {100 * (g / pub - 1):+.2f} %); full-order "
              f"bound {bound:.6g}; starts within 2 %: {rows[-1][9]}/{gs.size}; median per start "
              f"{rows[-1][11]:.1f} s CPU, {rows[-1][12]:.1f} s wall; all starts {wall:.0f} s wall (load "
              f"{os.getloadavg()[0]:.1f})\n  per start: {np.round(gs, 5).tolist()}\n  CPU s per start: "
              f"{np.round(r.start_cpu_s, 1).tolist()}\n  K = {np.array2string(K, precision=5)}", flush=True)
    print("\n| problem | states | gains | gamma (ours, re-verified) | stable | published best | gap | Nelder-Mead from ours "
          "| starts within 2 % | median s/start (CPU / wall) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, n, nk, g, st, _, nm, _, pub, near, ns, cpu, wall in rows:
        gap = f"{100 * (g / pub - 1):+.2f} %" if np.isfinite(pub) else "-"
        pubs = f"{pub:.4g}" if np.isfinite(pub) else "none found"
        print(f"| {name} | {n} | {nk} | {g:.4f} | {st} | {pubs} | {gap} | {nm:.4f} | {near}/{ns} | {cpu:.1f} / {wall:.1f} |")


if __name__ == "__main__":
    main()
