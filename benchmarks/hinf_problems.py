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
``flex20``    a lightly damped flexible structure (:func:`flex20`, seeds 0-2 as ``flex20s0`` ...): 20 modes from 1
              to 140 rad/s, 40 states, 2 non-collocated force actuators and 2 position sensors, static 2x2 output
              feedback whose best gains are 10^4-10^5 (the engine's scale-invariance problem; reference values
              from the gain-scale sweep of benchmarks/flex_reference.py).

:func:`rescaled` gives any problem with its control inputs and measurements in other units (the optimum's
gamma is the same, its gains are divided by the factors).

Each builder returns a :class:`Problem`. Run ``python benchmarks/bench_hinfstruct.py`` for the table.
"""

from __future__ import annotations

import copy
import dataclasses
import warnings

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.tune.blocks import FixedOrderSS, StaticGain, Structure


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


# modal mass of flex20's structure: its actuators' newtons move the modes by 1/MODAL_MASS_KG, so the optimal
# gains are this much larger than the loop gains they make
MODAL_MASS_KG = 500.0


def flex20(seed: int = 0) -> Problem:
    """A lightly damped flexible structure in modal form, one member of a seeded family.

    Modes ``q_k'' + 2 zeta w_k q_k' + w_k^2 q_k = phi_k(u, w)``, k = 1..20, with ``w_k`` from 1 to 140 rad/s
    (a beam-like ``k^2`` spacing with a seeded +-3 % jitter) and ``zeta = 0.005``. The mode shapes are those of a
    pinned-pinned beam, ``sin(k pi s)``, which fall into two symmetry groups about the middle (odd k symmetric,
    even k antisymmetric). Two force actuators at ``s = 0.5 -+ a`` and two position sensors at ``s = 0.5 -+ b``
    (a symmetric pair each, ``a != b``: non-collocated, so the sensor sees the actuator through modes of
    alternating sign), with seeded ``a``, ``b``; the actuators push in newtons on modes of :data:`MODAL_MASS_KG` (the
    disturbance and the displacements are in modal units). One disturbance force on the velocities, distributed as a
    seeded smooth load. Performance ``z = [diag(q) x; r u]`` with heavy state weights ``q`` drawn log-uniformly
    in [300, 3000] and a small control weight ``r = 1``; no sensor noise (``D21 = 0``). The best static 2x2
    position feedback known has gains of 10^4-10^5 N per unit displacement, nearly rank one (one combination of the
    sensors drives both actuators), and stabilises only in a thin band of gain scale: flex20s0's best (48,623, from
    benchmarks/flex_reference.py) has singular values 1.8e5 and 1.2e2 and is unstable at half and at twice its
    largest one. Local minima at lower gains abound (flex20s0: 55,022 at singular values 1.4e4 and 2.2e2, which 13
    of 50 random starts reach), and the start from K = 0 ends in a low-gain valley about 40 % above the best.
    """
    rng = np.random.default_rng(1000 + seed)
    n = 20
    k = np.arange(1, n + 1)
    wk = 1.0 + 139.0 * ((k**2 - 1) / (n**2 - 1)) * np.r_[1.0, 1.0 + 0.03 * rng.uniform(-1, 1, n - 2), 1.0]
    wk = np.sort(wk)
    zeta = 0.005
    a, b = rng.uniform(0.15, 0.4), rng.uniform(0.05, 0.3)
    shape = lambda s: np.sin(k * np.pi * s)  # noqa: E731
    Phi_u = np.column_stack([shape(0.5 - a), shape(0.5 + a)])          # (n, 2) modal forces per actuator
    Phi_y = np.vstack([shape(0.5 - b), shape(0.5 + b)])                # (2, n) modal displacements per sensor
    load = rng.uniform(0.5, 1.5, 4)
    s_grid = np.linspace(0.0, 1.0, 201)
    dist = np.array([np.trapezoid(np.sin(kk * np.pi * s_grid) * np.polyval(load, s_grid), s_grid) for kk in k])
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(wk**2), -np.diag(2 * zeta * wk)]])
    B1 = np.r_[np.zeros(n), dist][:, None]
    B2 = np.vstack([np.zeros((n, 2)), Phi_u / MODAL_MASS_KG])
    q = np.exp(rng.uniform(np.log(300.0), np.log(3000.0), 2 * n))
    C1 = np.vstack([np.diag(q), np.zeros((2, 2 * n))])
    D12 = np.vstack([np.zeros((2 * n, 2)), np.eye(2)])
    C2 = np.hstack([Phi_y, np.zeros((2, n))])
    P = _assemble(A, B1, B2, C1, C2, np.zeros((2 * n + 2, 1)), D12, np.zeros((2, 1)))
    return Problem(f"flex20s{seed}", P, 2, 2, "static", note="20 modes 1-140 rad/s, zeta 0.005, gains 1e3-1e4")


def rescaled(prob: Problem, u_scale, y_scale) -> Problem:
    """The same problem with control ``i`` in units ``u_scale[i]`` times larger (``B2, D12, D22`` columns times
    ``u_scale``) and measurement ``j`` in units ``1/y_scale[j]`` (``C2, D21, D22`` rows times ``y_scale``):
    ``K`` is optimal for ``prob`` exactly when ``diag(1/u_scale) K diag(1/y_scale)`` is for the result, with the
    same closed loop and gamma. Scalars apply to every channel. A block controller is copied with its start
    values mapped the same way (:meth:`rotorlab.tune.blocks.Block.io_exponents`), so both problems start from
    the same closed loop."""
    P = prob.P
    nz, nw = P.noutputs - prob.nmeas, P.ninputs - prob.ncon
    a = np.broadcast_to(np.asarray(u_scale, float), (prob.ncon,))
    c = np.broadcast_to(np.asarray(y_scale, float), (prob.nmeas,))
    Bs = np.r_[np.ones(nw), a]
    Cs = np.r_[np.ones(nz), c]
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    P2 = ct.ss(A, B * Bs, Cs[:, None] * C, Cs[:, None] * D * Bs, P.dt)
    ctrl = prob.controller
    if not isinstance(ctrl, str):
        ctrl = copy.deepcopy(ctrl)
        S = ctrl if isinstance(ctrl, Structure) else Structure([ctrl])
        eu, ey = S.io_exponents()
        S.set_values(S.values * np.exp(-(eu @ np.log(a) + ey @ np.log(c))))
    return dataclasses.replace(prob, name=f"{prob.name}[u*{a[0]:g},y*{c[0]:g}]", P=P2, controller=ctrl)


PROBLEMS = {f.__name__: f for f in (chain40, gain22, mimo8, mimo8d, mixsyn3, rand4)}
PROBLEMS.update({f"flex20s{s}": (lambda s=s: flex20(s)) for s in range(3)})
