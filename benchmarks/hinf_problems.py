"""The project's own families of hard structured H-inf problems (generated here, seeded, nothing copied).

Every problem is a generalised plant ``P`` with inputs ``[w; u]`` and outputs ``[z; y]``, a controller
structure and, where the structure is full order, the optimal bound from ``control.hinfsyn``:

``chain40``   a chain of 20 masses with light Rayleigh damping (modal damping 0.3-3 %), 40 states, two force
              actuators and two non-collocated velocity sensors; static 2x2 output feedback.
``gain22``    an unstable plant (pole at +20 coupled to a slow mode) whose first channel needs a feedback
              gain of about -22 before anything is stable; static 2x2 output feedback from K = 0.
``mimo8``     8 states with three unstable modes, 4 inputs, 6 measurements; static 4x6 output feedback.
``mimo8d``    ``mimo8`` sampled at 20 Hz (zero-order hold): the spectral-radius side of the engine.
``mixsyn3``   mixed sensitivity ``[W1 S; W2 KS]`` of a first-order plant: a full-order (3 states) controller.
``rand4``     a random lightly unstable 4-state plant, 2 inputs, 2 measurements: a full-order controller.

Each builder returns a :class:`Problem`. Run ``python benchmarks/bench_hinfstruct.py`` for the table.
"""

from __future__ import annotations

import dataclasses
import warnings

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.tune.blocks import FixedOrderSS, StaticGain


@dataclasses.dataclass
class Problem:
    name: str
    P: ct.StateSpace
    nmeas: int
    ncon: int
    controller: object  # "static" or a block
    full_order: bool = False
    note: str = ""

    def hinfsyn_bound(self) -> float:
        """Optimal full-order closed-loop norm (python-control hinfsyn, re-verified with ab13dd)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, CL, _, _ = ct.hinfsyn(self.P, self.nmeas, self.ncon)
        return lti.hinfnorm(CL)[0]


def _assemble(A, B1, B2, C1, C2, D11, D12, D21, D22=None, dt=0):
    D22 = np.zeros((C2.shape[0], B2.shape[1])) if D22 is None else D22
    B = np.hstack([B1, B2])
    C = np.vstack([C1, C2])
    D = np.block([[D11, D12], [D21, D22]])
    return ct.ss(A, B, C, D, dt) if dt else ct.ss(A, B, C, D)


def chain40(n_masses: int = 20) -> Problem:
    """Mass-spring chain fixed to a wall at the first mass, unit masses and springs (N/m), Rayleigh damping
    C = a M + b K chosen for 3 % damping of the lowest mode and 1.5 % of the highest."""
    n = n_masses
    K = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    K[-1, -1] = 1.0  # free end
    w = np.sqrt(np.linalg.eigvalsh(K))
    # zeta(w) = a/(2w) + b w/2 at the lowest and highest modes
    M2 = np.array([[1 / (2 * w[0]), w[0] / 2], [1 / (2 * w[-1]), w[-1] / 2]])
    a, b = np.linalg.solve(M2, [0.03, 0.015])
    Cd = a * np.eye(n) + b * K
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -Cd]])
    e = np.eye(n)
    force = lambda *idx: np.vstack([np.zeros((n, len(idx))), e[:, list(idx)]])  # noqa: E731
    B1 = np.hstack([force(4, 12), np.zeros((2 * n, 2))])          # disturbance forces, sensor noise
    B2 = force(0, 9)                                               # actuators at masses 1 and 10
    C1 = np.vstack([np.hstack([e[[n - 1, n // 2]], np.zeros((2, n))]), np.zeros((2, 2 * n))])
    D12 = np.vstack([np.zeros((2, 2)), 0.1 * np.eye(2)])           # tip and middle position, 0.1 x force
    C2 = np.hstack([np.zeros((2, n)), e[[0, n - 1]]])              # velocities of mass 1 and the tip
    D21 = np.hstack([np.zeros((2, 2)), 0.01 * np.eye(2)])
    D11 = np.zeros((4, 4))
    return Problem("chain40", _assemble(A, B1, B2, C1, C2, D11, D12, D21), 2, 2, "static",
                   note="40 states, lightly damped, non-collocated")


def gain22() -> Problem:
    A = np.array([[20.0, 2.0, 0.0], [0.0, -1.0, 1.0], [-3.0, 0.0, -2.0]])
    B1 = np.hstack([np.eye(3), np.zeros((3, 2))])
    B2 = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    C1 = np.vstack([np.eye(3), np.zeros((2, 3))])
    D12 = np.vstack([np.zeros((3, 2)), 0.05 * np.eye(2)])
    C2 = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    D21 = np.hstack([np.zeros((2, 3)), 0.1 * np.eye(2)])
    return Problem("gain22", _assemble(A, B1, B2, C1, C2, np.zeros((5, 5)), D12, D21), 2, 2, "static",
                   note="unstable, needs |k11| > 20 (K = 0 start)")


def _mimo8(seed: int = 8):
    rng = np.random.default_rng(seed)
    n, m, p = 8, 4, 6
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = np.r_[0.6, 0.3, 0.1, -0.5, -1.0, -1.5, -2.0, -3.0]
    A = Q @ np.diag(lam) @ Q.T + 0.3 * rng.standard_normal((n, n)) @ np.diag([0, 0, 0, 1, 1, 1, 1, 1]) @ Q.T
    B2 = rng.standard_normal((n, m))
    C2 = rng.standard_normal((p, n))
    B1 = np.hstack([0.5 * rng.standard_normal((n, 2)), np.zeros((n, p))])
    C1 = np.vstack([rng.standard_normal((2, n)), np.zeros((m, n))])
    D12 = np.vstack([np.zeros((2, m)), 0.3 * np.eye(m)])
    D21 = np.hstack([np.zeros((p, 2)), 0.1 * np.eye(p)])
    return A, B1, B2, C1, C2, np.zeros((2 + m, 2 + p)), D12, D21


def mimo8() -> Problem:
    return Problem("mimo8", _assemble(*_mimo8()), 6, 4, "static", note="8 states, 3 unstable, 4 in, 6 meas")


def mimo8d() -> Problem:
    P = lti.c2d_zoh(_assemble(*_mimo8()), 0.05)
    return Problem("mimo8d", P, 6, 4, StaticGain(6, 4, dt=0.05), note="mimo8 at 20 Hz (ZOH)")


def mixsyn3() -> Problem:
    G = ct.tf([1], [1, -0.5])  # unstable first-order plant
    W1 = ct.tf([0.5, 2], [1, 0.02])
    W2 = ct.tf([0.5, 0.1], [0.01, 1])
    P = ct.minreal(ct.augw(G, W1, W2), verbose=False)
    return Problem("mixsyn3", P, 1, 1, FixedOrderSS(P.nstates, 1, 1, seed=0), full_order=True,
                   note="W1 S / W2 KS, full order")


def rand4() -> Problem:
    rng = np.random.default_rng(4)
    n = 4
    A = rng.standard_normal((n, n))
    A = A - (np.max(np.linalg.eigvals(A).real) - 0.4) * np.eye(n)  # one or two modes at +0.4
    B1 = np.hstack([rng.standard_normal((n, 2)), np.zeros((n, 2))])
    B2 = rng.standard_normal((n, 2))
    C1 = np.vstack([rng.standard_normal((2, n)), np.zeros((2, n))])
    C2 = rng.standard_normal((2, n))
    D12 = np.vstack([np.zeros((2, 2)), 0.5 * np.eye(2)])
    D21 = np.hstack([np.zeros((2, 2)), 0.5 * np.eye(2)])
    P = _assemble(A, B1, B2, C1, C2, np.zeros((4, 4)), D12, D21)
    return Problem("rand4", P, 2, 2, FixedOrderSS(n, 2, 2, seed=0), full_order=True,
                   note="random unstable, 2x2, full order")


PROBLEMS = {f.__name__: f for f in (chain40, gain22, mimo8, mimo8d, mixsyn3, rand4)}
