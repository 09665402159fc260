"""Tunable controller blocks for structured H-inf synthesis.

A block is a fixed-structure LTI system whose state-space matrices depend smoothly on a parameter vector.
The realisation (state count, signal layout) never depends on the parameter values, so the closed loop keeps
one fixed state dimension throughout the optimisation (``rotorlab.lti.pid_tf`` calls ``minreal`` and would
drop states when a gain crosses zero, which is why the PID realisations are written out here and checked
against ``pid_tf`` / ``pid2_ss`` in the tests).

Blocks combine into a block-diagonal :class:`Structure`: the controller inputs are the blocks' inputs in
order, its outputs the blocks' outputs in order. Each parameter may be fixed or bounded.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import control as ct
import numpy as np

from rotorlab.lti import as_ss

__all__ = ["Param", "Block", "StaticGain", "PID", "PID2", "FixedOrderSS", "Custom", "Structure"]

_UNBOUNDED = (-np.inf, np.inf)


@dataclasses.dataclass
class Param:
    """One scalar tunable: its value, whether it is fixed, and its bounds (inclusive)."""

    name: str
    value: float
    fixed: bool = False
    lower: float = -np.inf
    upper: float = np.inf


class Block:
    """Base class: a parametrised LTI block with ``ny`` inputs (measurements) and ``nu`` outputs (controls).

    Subclasses define :meth:`matrices` (theta -> A, B, C, D) for the block's own parameter vector; the state
    count ``nx`` must not depend on theta.
    """

    # True when (A, B, C, D) are linear in theta (no constant part): the derivatives are then exact unit-vector
    # matrices that do not depend on theta
    linear = False

    def __init__(self, name: str, params: Sequence[Param], ny: int, nu: int, nx: int, dt: float = 0.0):
        self.name = name
        self.params = list(params)
        self.ny, self.nu, self.nx, self.dt = int(ny), int(nu), int(nx), float(dt or 0.0)

    def matrices(self, theta: np.ndarray):
        raise NotImplementedError

    def io_exponents(self):
        """How each parameter carries the units of the block's signals: two arrays ``(eu, ey)`` of shapes
        ``(nparams, nu)`` and ``(nparams, ny)`` such that scaling the block's outputs (controls) by ``a`` and
        its inputs (measurements) by ``c``, i.e. ``K -> diag(a) K diag(c)``, is the same as multiplying
        parameter ``p`` by ``prod_i a_i ** eu[p, i] * prod_j c_j ** ey[p, j]``.

        The structured H-inf engine sizes its variables with this (a parameter with all-zero rows, like a
        filter time constant, is not rescaled by the plant's units). The base class declares every parameter
        unit-free, which is right for a block whose gains do not scale with its signals; blocks whose gains do
        override it.

        Examples
        --------
        >>> from rotorlab.tune.blocks import PID
        >>> eu, ey = PID(kp=2.0, ki=1.0, kd=0.1, tf=0.01).io_exponents()
        >>> eu[:, 0].tolist(), ey[:, 0].tolist()  # kp, ki, kd scale with the loop, tf does not
        ([1.0, 1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 0.0])
        """
        n = len(self.params)
        return np.zeros((n, self.nu)), np.zeros((n, self.ny))

    def matrix_derivatives(self, theta: np.ndarray, idx) -> list:
        """d(A, B, C, D)/d theta_i for the block parameters ``idx``, by central differences.

        Block maps are low-degree rational functions of theta (linear for most blocks), so a central
        difference is accurate to ~1e-9 and keeps user-defined blocks free of hand-written derivatives;
        blocks marked ``linear`` get exact ones (the matrices of each unit parameter vector), others on the
        optimiser's hot path override this with exact derivatives.
        """
        if self.linear:
            return _unit_derivatives(self, idx)
        th = np.asarray(theta, float)
        out = []
        for i in idx:
            h = 1e-6 * max(1.0, abs(th[i]))
            tp, tm = th.copy(), th.copy()
            tp[i] += h
            tm[i] -= h
            out.append(tuple((p - m) / (2 * h) for p, m in zip(self.matrices(tp), self.matrices(tm))))
        return out

    # -- conveniences -------------------------------------------------------------------------------------
    def fix(self, *names: str) -> Block:
        """Fix the named parameters at their current values (returns self for chaining)."""
        for n in names:
            self._param(n).fixed = True
        return self

    def free(self, *names: str) -> Block:
        for n in names:
            self._param(n).fixed = False
        return self

    def bound(self, name: str, lower: float = -np.inf, upper: float = np.inf) -> Block:
        p = self._param(name)
        p.lower, p.upper = float(lower), float(upper)
        return self

    def _param(self, name):
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"block '{self.name}' has no parameter '{name}'; it has {[p.name for p in self.params]}")

    @property
    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.params], dtype=float)

    def ss(self, theta=None) -> ct.StateSpace:
        A, B, C, D = self.matrices(self.values if theta is None else np.asarray(theta, float))
        return ct.ss(A, B, C, D, self.dt if self.dt > 0 else 0)


class StaticGain(Block):
    """Static gain ``u = K y`` with ``K`` of shape ``(nu, ny)``; parameters named ``k[i,j]``."""

    linear = True

    def __init__(self, ny: int, nu: int, value=None, name: str = "K", dt: float = 0.0):
        K0 = np.zeros((nu, ny)) if value is None else np.asarray(value, float).reshape(nu, ny)
        params = [Param(f"k[{i},{j}]", float(K0[i, j])) for i in range(nu) for j in range(ny)]
        super().__init__(name, params, ny, nu, 0, dt)

    def matrices(self, theta):
        return (np.zeros((0, 0)), np.zeros((0, self.ny)), np.zeros((self.nu, 0)),
                np.asarray(theta, float).reshape(self.nu, self.ny))

    def io_exponents(self):
        """``k[i,j]`` carries the units of control ``i`` over measurement ``j``."""
        i, j = np.divmod(np.arange(self.nu * self.ny), self.ny)
        return np.eye(self.nu)[i], np.eye(self.ny)[j]


def _unit_derivatives(block, idx):
    """Derivatives of a block linear in its parameters: the matrices of each unit parameter vector."""
    out = []
    for i in idx:
        e = np.zeros(len(block.params))
        e[i] = 1.0
        out.append(block.matrices(e))
    return out


def _pid_parts(kp, ki, kd, tf, dt, integral, derivative):
    """Integrator and derivative-filter realisations, forward Euler when ``dt > 0`` (as rotorlab.lti.pid_tf):

    integral ``ki * I`` with ``x_i+ = x_i + dt e`` (discrete) or ``x_i' = e``; derivative ``kd/(tf + I)``
    realised as ``(kd/tf) (e - x_d)`` with ``x_d+ = (1 - dt/tf) x_d + (dt/tf) e`` or ``x_d' = (e - x_d)/tf``.
    """
    a_i = 1.0 if dt > 0 else 0.0
    b_i = dt if dt > 0 else 1.0
    if derivative:
        if dt > 0:
            a_d, b_d = 1.0 - dt / tf, dt / tf
        else:
            a_d, b_d = -1.0 / tf, 1.0 / tf
    else:
        a_d = b_d = 0.0
    return a_i, b_i, a_d, b_d


class PID2(Block):
    """Two-degree-of-freedom PID, inputs ``(r, y)``, output
    ``u = kp (b r - y) + ki I (r - y) + kd/(tf + I) (c r - y)`` (``I = 1/s`` or forward-Euler ``dt/(z-1)``).

    ``integral=False`` / ``derivative=False`` drop the state (and fix ``ki`` / ``kd``, ``tf`` at 0), e.g. for
    the outer PD of the attitude cascade. ``tf`` is bounded below by ``dt/2`` (discrete derivative filter
    stable) and ``b``, ``c`` by [0, 1].
    """

    def __init__(self, kp=1.0, ki=0.0, kd=0.0, tf=0.1, b=1.0, c=1.0, dt: float = 0.0, *, name: str = "pid2",
                 integral: bool = True, derivative: bool = True):
        self.integral, self.derivative = bool(integral), bool(derivative)
        dt = float(dt or 0.0)
        tf_lo = 0.5 * dt * 1.02 if dt > 0 else 1e-5
        params = [
            Param("kp", float(kp)),
            Param("ki", float(ki) if integral else 0.0, fixed=not integral),
            Param("kd", float(kd) if derivative else 0.0, fixed=not derivative),
            Param("tf", float(tf) if derivative else 0.0, fixed=not derivative, lower=tf_lo if derivative else -np.inf),
            Param("b", float(b), lower=0.0, upper=1.0),
            Param("c", float(c), lower=0.0, upper=1.0),
        ]
        super().__init__(name, params, 2, 1, int(integral) + int(derivative), dt)

    def matrices(self, theta):
        kp, ki, kd, tf, b, c = (float(v) for v in theta)
        a_i, b_i, a_d, b_d = _pid_parts(kp, ki, kd, tf, self.dt, self.integral, self.derivative)
        A, B, C = [], [], []
        if self.integral:
            A.append(a_i)
            B.append([b_i, -b_i])
            C.append(ki)
        if self.derivative:
            A.append(a_d)
            B.append([b_d * c, -b_d])
            C.append(-kd / tf)
        D = [[kp * b + (kd / tf * c if self.derivative else 0.0), -kp - (kd / tf if self.derivative else 0.0)]]
        n = len(A)
        return (np.diag(A).reshape(n, n), np.asarray(B, float).reshape(n, 2), np.asarray(C, float).reshape(1, n),
                np.asarray(D, float))

    def io_exponents(self):
        """``kp``, ``ki``, ``kd`` carry the units of the output over the inputs (``r`` and ``y`` share one
        unit, half each); ``tf``, ``b``, ``c`` are unit-free."""
        gain = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])[:, None]
        return gain * np.ones((1, 1)), gain * np.full((1, 2), 0.5)

    def matrix_derivatives(self, theta, idx):
        """Exact d(A, B, C, D)/d theta_i of the realisation in :meth:`matrices` (checked against central
        differences in the tests): the tuner asks for them at every SLSQP callback."""
        kp, ki, kd, tf, b, c = (float(v) for v in theta)
        n = self.nx
        i_d = int(self.integral)  # row/column of the derivative state
        discrete = self.dt > 0
        out = []
        for i in idx:
            dA, dB, dC, dD = np.zeros((n, n)), np.zeros((n, 2)), np.zeros((1, n)), np.zeros((1, 2))
            if i == 0:                                           # kp
                dD[0] = [b, -1.0]
            elif i == 1 and self.integral:                       # ki
                dC[0, 0] = 1.0
            elif i == 2 and self.derivative:                     # kd
                dC[0, i_d] = -1.0 / tf
                dD[0] = [c / tf, -1.0 / tf]
            elif i == 3 and self.derivative:                     # tf: a_d = 1 - dt/tf or -1/tf, b_d = dt/tf or 1/tf
                db_d = -(self.dt if discrete else 1.0) / tf**2
                dA[i_d, i_d] = -db_d
                dB[i_d] = [db_d * c, -db_d]
                dC[0, i_d] = kd / tf**2
                dD[0] = [-kd * c / tf**2, kd / tf**2]
            elif i == 4:                                         # b
                dD[0, 0] = kp
            elif i == 5:                                         # c
                if self.derivative:
                    dB[i_d, 0] = self.dt / tf if discrete else 1.0 / tf
                    dD[0, 0] = kd / tf
            out.append((dA, dB, dC, dD))
        return out


class PID(Block):
    """One-degree-of-freedom PID on a single input ``e``: ``u = kp e + ki I e + kd/(tf + I) e``
    (same realisation as :class:`PID2` with ``b = c = 1`` and ``r = e, y = 0``)."""

    def __init__(self, kp=1.0, ki=0.0, kd=0.0, tf=0.1, dt: float = 0.0, *, name: str = "pid",
                 integral: bool = True, derivative: bool = True):
        self._inner = PID2(kp, ki, kd, tf, 1.0, 1.0, dt, name=name, integral=integral, derivative=derivative)
        super().__init__(name, self._inner.params[:4], 1, 1, self._inner.nx, dt)

    def matrices(self, theta):
        A, B, C, D = self._inner.matrices(np.r_[np.asarray(theta, float), 1.0, 1.0])
        return A, B[:, :1], C, D[:, :1]

    def io_exponents(self):
        """``kp``, ``ki``, ``kd`` carry the units of the output over the input; ``tf`` is unit-free."""
        gain = np.array([1.0, 1.0, 1.0, 0.0])[:, None]
        return gain.copy(), gain.copy()

    def matrix_derivatives(self, theta, idx):
        d = self._inner.matrix_derivatives(np.r_[np.asarray(theta, float), 1.0, 1.0], idx)
        return [(dA, dB[:, :1], dC, dD[:, :1]) for dA, dB, dC, dD in d]


class FixedOrderSS(Block):
    """Fixed-order state-space controller of order ``n``: every entry of A, B, C, D is a parameter.

    The start is drawn with ``seed``: a stable, well-damped A (continuous: eigenvalues in the left half-plane;
    discrete: inside radius 0.5) and small B, C, D.
    """

    linear = True

    def __init__(self, n: int, ny: int, nu: int, dt: float = 0.0, *, name: str = "K", seed=0, scale: float = 0.1):
        rng = np.random.default_rng(seed)
        A0 = rng.standard_normal((n, n)) * scale
        if dt:
            A0 = 0.5 * A0 / max(1.0, np.max(np.abs(np.linalg.eigvals(A0)), initial=0.0))
        else:
            A0 = A0 - np.eye(n)
        B0 = rng.standard_normal((n, ny)) * scale
        C0 = rng.standard_normal((nu, n)) * scale
        D0 = np.zeros((nu, ny))
        params = []
        for tag, M in (("A", A0), ("B", B0), ("C", C0), ("D", D0)):
            params += [Param(f"{tag}[{i},{j}]", float(M[i, j])) for i in range(M.shape[0]) for j in range(M.shape[1])]
        self._n = n
        super().__init__(name, params, ny, nu, n, dt)

    def io_exponents(self):
        """A is unit-free (its state's units are the controller's own choice: B takes the inputs' units and C
        the outputs', so ``diag(a) K diag(c)`` is ``(A, B diag(c), diag(a) C, diag(a) D diag(c))``)."""
        n, ny, nu = self._n, self.ny, self.nu
        eu = [np.zeros((n * n + n * ny, nu)), np.repeat(np.eye(nu), n, axis=0), np.repeat(np.eye(nu), ny, axis=0)]
        ey = [np.zeros((n * n, ny)), np.tile(np.eye(ny), (n, 1)), np.zeros((nu * n, ny)), np.tile(np.eye(ny), (nu, 1))]
        return np.vstack(eu), np.vstack(ey)

    def matrices(self, theta):
        n, ny, nu = self._n, self.ny, self.nu
        th = np.asarray(theta, float)
        i = 0
        out = []
        for r, c in ((n, n), (n, ny), (nu, n), (nu, ny)):
            out.append(th[i:i + r * c].reshape(r, c))
            i += r * c
        return tuple(out)


class Custom(Block):
    """User block: ``fn(theta) -> StateSpace`` (or ``(A, B, C, D)``) with named parameters ``names`` starting at
    ``values``; the state count must not change with theta."""

    def __init__(self, fn: Callable, names: Sequence[str], values: Sequence[float], *, name: str = "custom",
                 dt: float = 0.0):
        self.fn = fn
        A, B, C, D = self._call(np.asarray(values, float))
        super().__init__(name, [Param(n, float(v)) for n, v in zip(names, values)], D.shape[1], D.shape[0],
                         A.shape[0], dt)

    def _call(self, theta):
        out = self.fn(theta)
        if isinstance(out, (ct.StateSpace, ct.TransferFunction)):
            s = as_ss(out)
            return tuple(np.asarray(M, float) for M in (s.A, s.B, s.C, s.D))
        return tuple(np.atleast_2d(np.asarray(M, float)) for M in out)

    def matrices(self, theta):
        A, B, C, D = self._call(theta)
        if A.shape[0] != self.nx:
            raise ValueError(f"custom block '{self.name}' changed its state count from {self.nx} to {A.shape[0]}")
        return A, B, C, D


class Structure:
    """Block-diagonal controller of several blocks; parameters are named ``block.param``."""

    def __init__(self, blocks: Sequence[Block]):
        self.blocks = list(blocks)
        if not self.blocks:
            raise ValueError("a controller structure needs at least one block")
        names = [b.name for b in self.blocks]
        if len(set(names)) != len(names):
            raise ValueError(f"block names must be unique, got {names}")
        dts = {b.dt for b in self.blocks}
        if len(dts) > 1:
            raise ValueError(f"all blocks must share one sample time, got {sorted(dts)}")
        self.dt = dts.pop()
        self.ny = sum(b.ny for b in self.blocks)
        self.nu = sum(b.nu for b in self.blocks)
        self.nx = sum(b.nx for b in self.blocks)
        self._slices = []
        i = 0
        for b in self.blocks:
            self._slices.append(slice(i, i + len(b.params)))
            i += len(b.params)

    @property
    def params(self) -> list[Param]:
        return [p for b in self.blocks for p in b.params]

    @property
    def names(self) -> list[str]:
        return [f"{b.name}.{p.name}" for b in self.blocks for p in b.params]

    @property
    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.params], float)

    def set_values(self, theta) -> None:
        for p, v in zip(self.params, np.asarray(theta, float)):
            p.value = float(v)

    def matrices(self, theta):
        """Block-diagonal (A, B, C, D) of the whole controller at ``theta``."""
        th = np.asarray(theta, float)
        key = th.tobytes()
        if getattr(self, "_mcache", (None,))[0] == key:  # the SQP revisits the same point many times
            return self._mcache[1]
        A = np.zeros((self.nx, self.nx))
        B = np.zeros((self.nx, self.ny))
        C = np.zeros((self.nu, self.nx))
        D = np.zeros((self.nu, self.ny))
        ix = iy = iu = 0
        for b, sl in zip(self.blocks, self._slices):
            a, bb, c, d = b.matrices(th[sl])
            A[ix:ix + b.nx, ix:ix + b.nx] = a
            B[ix:ix + b.nx, iy:iy + b.ny] = bb
            C[iu:iu + b.nu, ix:ix + b.nx] = c
            D[iu:iu + b.nu, iy:iy + b.ny] = d
            ix, iy, iu = ix + b.nx, iy + b.ny, iu + b.nu
        self._mcache = (key, (A, B, C, D))
        return A, B, C, D

    def io_exponents(self):
        """:meth:`Block.io_exponents` of every parameter against the whole controller's outputs (``nu``) and
        inputs (``ny``): arrays ``(nparams, nu)`` and ``(nparams, ny)``."""
        n = len(self.params)
        eu, ey = np.zeros((n, self.nu)), np.zeros((n, self.ny))
        iy = iu = 0
        for b, sl in zip(self.blocks, self._slices):
            bu, by = b.io_exponents()
            eu[sl, iu:iu + b.nu], ey[sl, iy:iy + b.ny] = bu, by
            iy, iu = iy + b.ny, iu + b.nu
        return eu, ey

    def matrix_derivatives(self, theta, free: np.ndarray):
        """d(A, B, C, D)/d theta_i of the whole controller for each free index, stacked: four arrays with a
        leading axis over the free parameters. Each block differentiates only its own parameters (see
        :meth:`Block.matrix_derivatives`); the rest of each slice is zero."""
        th = np.asarray(theta, float)
        free = np.asarray(free, bool)
        # blocks linear in theta (static gains, free state-space matrices) have the same derivatives everywhere:
        # the optimisers ask for them at every gradient evaluation
        key = (b"" if all(b.linear for b in self.blocks) else th.tobytes(), free.tobytes())
        if getattr(self, "_dcache", (None,))[0] == key:  # the SQP asks for the same point's derivatives often
            return self._dcache[1]
        nf = int(free.sum())
        dA = np.zeros((nf, self.nx, self.nx))
        dB = np.zeros((nf, self.nx, self.ny))
        dC = np.zeros((nf, self.nu, self.nx))
        dD = np.zeros((nf, self.nu, self.ny))
        k = ix = iy = iu = 0
        for b, sl in zip(self.blocks, self._slices):
            idx = np.flatnonzero(free[sl])
            for d in b.matrix_derivatives(th[sl], idx):
                dA[k, ix:ix + b.nx, ix:ix + b.nx] = d[0]
                dB[k, ix:ix + b.nx, iy:iy + b.ny] = d[1]
                dC[k, iu:iu + b.nu, ix:ix + b.nx] = d[2]
                dD[k, iu:iu + b.nu, iy:iy + b.ny] = d[3]
                k += 1
            ix, iy, iu = ix + b.nx, iy + b.ny, iu + b.nu
        self._dcache = (key, (dA, dB, dC, dD))
        return dA, dB, dC, dD

    def ss(self, theta=None) -> ct.StateSpace:
        A, B, C, D = self.matrices(self.values if theta is None else theta)
        return ct.ss(A, B, C, D, self.dt if self.dt > 0 else 0)
