"""Held-out check on published static-output-feedback H-inf problems of COMPleib (F. Leibfritz, "COMPleib:
COnstrained Matrix-optimization Problem library", Univ. Trier, 2004/2006), solved as a user would:
``hinfstruct(P, "static", ny, nu, starts=N)`` with every result re-verified (closed-loop poles, ab13dd norm).

The matrices are transcribed from the Mathematica export of COMPleib in the NCAlgebra repository
(github.com/NCAlgebra/NC, TESTING/NCSDP/COMPleib/MmaCOMPleib/HE3.m and HE4.m, commit b4bf96d); the
problem is ``dx = A x + B1 w + B u, z = C1 x + D11 w + D12 u, y = C x + D21 w`` (COMPleib's names; C is
called CC there). Both are the 8-state helicopter models with 4 inputs and 6 measurements.

The full-order ``control.hinfsyn`` value is printed as a lower bound (a static gain cannot beat it). The
published best static values (the HIFOO and hinfstruct benchmark tables) could not be read from any source
reachable here, so no published number is hard-coded.

Run: ``python benchmarks/compleib.py [--starts 20] [--jobs 2]``.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import control as ct  # noqa: E402
import numpy as np  # noqa: E402

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

PROBLEMS = {"HE3": HE3, "HE4": HE4}


def plant(d):
    """Generalised plant ``[w; u] -> [z; y]`` with D22 = 0 (COMPleib's convention)."""
    A, B1, B, C1, C, D11, D12, D21 = (np.asarray(d[k], float) for k in ("A", "B1", "B", "C1", "C", "D11", "D12",
                                                                          "D21"))
    D = np.block([[D11, D12], [D21, np.zeros((C.shape[0], B.shape[1]))]])
    return ct.ss(A, np.hstack([B1, B]), np.vstack([C1, C]), D), C.shape[0], B.shape[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--starts", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS))
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
        cl = closed_loop(P, ny, nu, r.controller)
        g, _ = lti.hinfnorm(cl)
        stable = bool(np.max(np.linalg.eigvals(np.asarray(cl.A)).real) < 0)
        try:
            _, CLf, _, _ = ct.hinfsyn(P, ny, nu)
            bound = lti.hinfnorm(CLf)[0]
        except Exception as exc:  # singular D12/D21 (HE4 has D21 = 0): hinfsyn's rank conditions fail
            bound, why = np.nan, type(exc).__name__
        gs = np.array(r.starts)
        rows.append((name, g, stable, bound, int(np.sum(gs <= g * 1.02)), gs.size, np.median(r.start_cpu_s)))
        print(f"{name}: gamma {g:.6g} (re-verified), closed loop stable: {stable}, full-order bound {bound:.6g}"
              f"{'' if np.isfinite(bound) else ' (' + why + ')'}, starts within 2 %: {rows[-1][4]}/{gs.size}, "
              f"median CPU s/start {rows[-1][6]:.1f}, all starts {wall:.0f} s wall\n  per start: "
              f"{np.round(gs, 5).tolist()}\n  K = {np.array2string(np.asarray(r.controller.D), precision=5)}",
              flush=True)
    print("\n| problem | gamma (ours, verified) | stable | full-order bound | starts within 2 % | median CPU s/start |")
    print("|---|---|---|---|---|---|")
    for name, g, st, b, near, n, cpu in rows:
        print(f"| {name} | {g:.4f} | {st} | {b:.4f} | {near}/{n} | {cpu:.1f} |")


if __name__ == "__main__":
    main()
