"""Structured (fixed-order, fixed-structure) H-inf synthesis, in the spirit of Apkarian & Noll (2006) and
MATLAB's ``hinfstruct`` / ``systune``.

The problem ``min_theta ||F_l(P, K(theta))||_inf`` subject to internal stability is non-convex and
non-smooth: the norm is a maximum over frequency of the largest singular value. It is solved here as an
epigraph problem over an adaptively refined set of active frequencies::

    minimise t  s.t.  sigma_max(W(w_i) T(theta, j w_i)) <= t   for the active frequencies w_i
                      closed-loop eigenvalues inside the stability region

with ``scipy.optimize.minimize(method="SLSQP")``, analytic gradients of the singular values
(``d sigma = Re(u^H dT v)`` with ``dT = P12 (I - K P22)^-1 dK (I - P22 K)^-1 P21``) and of the eigenvalues
(``d lambda = y^H dA x / y^H x``), inside a trust region whose steps are accepted only when the objective
re-evaluated on the whole frequency axis decreases. After every step the local peaks of the new singular
value curve (dense grid, then a bounded scalar refinement, plus the exact ab13dd peak) join the active set,
so the method tracks moving and newly appearing peaks instead of stalling at a kink.

The same engine serves several weighted channels at once (soft goals minimised, hard goals kept <= 1), which
is how :mod:`rotorlab.tune.cascade` tunes against systune-like goals.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import time
from typing import Sequence

import control as ct
import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize

from rotorlab import lti
from rotorlab.tune.blocks import Block, StaticGain, Structure

__all__ = ["Channel", "HinfstructResult", "hinfstruct", "closed_loop", "optimise", "NotStabilisableError"]


# hard goals are enforced at this level inside the QP so that the verified value lands below 1 despite the
# linearisation and the finite active frequency set
HARD_BOUND = 0.995


class NotStabilisableError(ValueError):
    """No stabilising controller of the given structure was found from any start."""


@dataclasses.dataclass
class Channel:
    """One weighted closed-loop transfer ``w -> z`` of ``F_l(P, K)``.

    Parameters
    ----------
    P : control.StateSpace
        Generalised plant, inputs ``[w; u]`` and outputs ``[z; y]`` with ``nmeas`` = len(y), ``ncon`` = len(u).
    weight : LTI or None
        Scalar frequency weight; the channel value at ``w`` is ``|weight(jw)| * sigma_max(T + offset)``
        (``mode="max"``) or ``|weight(jw)| / sigma_min(T + offset)`` (``mode="min"``, a minimum gain).
    band_rad_s : (lo, hi)
        Frequencies (rad/s) where the channel counts.
    hard : bool
        Hard goals are constraints (value <= 1), soft goals are minimised (their maximum).
    """

    P: ct.StateSpace
    nmeas: int
    ncon: int
    weight: object = None
    offset: float = 0.0
    mode: str = "max"
    band_rad_s: tuple = (0.0, np.inf)
    hard: bool = False
    name: str = "channel"
    npoints: int = 300
    exact_peak: bool = False  # also add the ab13dd peak of the (unweighted, full-band) closed loop

    def __post_init__(self):
        P = lti.as_ss(self.P)
        self.P = P
        for tag, M in zip("ABCD", (P.A, P.B, P.C, P.D)):
            if not np.all(np.isfinite(np.asarray(M, float))):
                raise ValueError(f"channel '{self.name}': the plant's {tag} matrix contains NaN or Inf")
        if not (0 <= self.nmeas < P.noutputs and 0 <= self.ncon < P.ninputs):
            raise ValueError(
                f"channel '{self.name}': nmeas={self.nmeas}, ncon={self.ncon} do not fit a plant with "
                f"{P.noutputs} outputs and {P.ninputs} inputs (need at least one performance input and output)")
        self.nz, self.nw = P.noutputs - self.nmeas, P.ninputs - self.ncon
        self.dt = float(P.dt) if lti.is_discrete(P) else 0.0
        lo, hi = self.band_rad_s
        nyq = np.pi / self.dt if self.dt else np.inf
        hi = min(hi, nyq * 0.9999)
        if not np.isfinite(hi) or lo <= 0:
            ev = np.abs(np.linalg.eigvals(np.asarray(P.A, float))) if P.nstates else np.array([1.0])
            if self.dt:
                ev = np.abs(np.log(np.maximum(ev, 1e-12))) / self.dt
            ev = ev[ev > 1e-9]
            wmin = (ev.min() if ev.size else 1.0) * 1e-3
            wmax = (ev.max() if ev.size else 1.0) * 1e3
            lo = lo if lo > 0 else min(wmin, 1e-3)
            hi = hi if np.isfinite(hi) else max(wmax, 1e3)
        self.lo, self.hi = float(lo), float(hi)
        self._abcd = tuple(np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
        self.grid = np.logspace(np.log10(self.lo), np.log10(self.hi), self.npoints)
        self.Pgrid = self.plant_at(self.grid)
        self.Wgrid = self._weight(self.grid)

    def _weight(self, w):
        if self.weight is None:
            return np.ones(np.size(w))
        if callable(self.weight) and not isinstance(self.weight, (ct.StateSpace, ct.TransferFunction)):
            return np.asarray(self.weight(np.asarray(w, float)), float)
        return np.abs(lti.freqresp(self.weight, w)[:, 0, 0])

    def points(self, w):
        """Complex evaluation points (``jw`` or ``exp(jw dt)``) of the controller at ``w`` rad/s."""
        w = np.asarray(w, float)
        return np.exp(1j * w * self.dt) if self.dt else 1j * w

    def plant_at(self, w):
        """P(jw) (nf, p, m): one batched solve over all frequencies (the plants here have at most a few
        dozen states, where this beats the per-point Hessenberg loop of rotorlab.lti.freqresp)."""
        A, B, C, D = self._abcd
        w = np.atleast_1d(np.asarray(w, float))
        if A.shape[0] == 0:
            return np.broadcast_to(D, (w.size,) + D.shape).astype(complex)
        pts = self.points(w)
        X = np.linalg.solve(pts[:, None, None] * np.eye(A.shape[0]) - A, np.broadcast_to(B, (w.size,) + B.shape))
        return C @ X + D


def closed_loop(P, nmeas: int, ncon: int, K) -> ct.StateSpace:
    """Lower LFT ``F_l(P, K)`` as a StateSpace (states: plant then controller), with ``u = K y``."""
    P = lti.as_ss(P)
    K = lti.as_ss(K)
    mats = _cl_matrices(P, nmeas, ncon, *(np.asarray(M, float) for M in (K.A, K.B, K.C, K.D)))
    return ct.ss(*mats, P.dt)


def _partition(P, nmeas, ncon):
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    nz, nw = C.shape[0] - nmeas, B.shape[1] - ncon
    return dict(A=A, B1=B[:, :nw], B2=B[:, nw:], C1=C[:nz], C2=C[nz:], D11=D[:nz, :nw], D12=D[:nz, nw:],
                D21=D[nz:, :nw], D22=D[nz:, nw:])


def _cl_matrices(P, nmeas, ncon, Ak, Bk, Ck, Dk, part=None):
    p = part or _partition(P, nmeas, ncon)
    A, B1, B2, C1, C2 = p["A"], p["B1"], p["B2"], p["C1"], p["C2"]
    D11, D12, D21, D22 = p["D11"], p["D12"], p["D21"], p["D22"]
    IDD = np.eye(ncon) - Dk @ D22
    E = np.linalg.inv(IDD)
    if not np.all(np.isfinite(E)) or np.abs(E).max() > 1e12:
        raise ValueError("the interconnection is not well posed: I - Dk D22 is singular")
    EDk = E @ Dk
    Acl = np.block([[A + B2 @ EDk @ C2, B2 @ E @ Ck],
                    [Bk @ (C2 + D22 @ EDk @ C2), Ak + Bk @ D22 @ E @ Ck]])
    Bcl = np.vstack([B1 + B2 @ EDk @ D21, Bk @ (D21 + D22 @ EDk @ D21)])
    Ccl = np.hstack([C1 + D12 @ EDk @ C2, D12 @ E @ Ck])
    Dcl = D11 + D12 @ EDk @ D21
    return Acl, Bcl, Ccl, Dcl


def _dAcl(part, Km, dKm):
    """Exact derivatives of the closed-loop A along each controller-matrix direction (dAk, dBk, dCk, dDk),
    using ``dE = E dDk D22 E`` for ``E = (I - Dk D22)^-1``."""
    Ak, Bk, Ck, Dk = Km
    B2, C2, D22 = part["B2"], part["C2"], part["D22"]
    E = np.linalg.inv(np.eye(Dk.shape[0]) - Dk @ D22)
    EDk = E @ Dk
    out = []
    for dA, dB, dC, dD in dKm:
        dE = E @ dD @ D22 @ E
        dEDk = dE @ Dk + E @ dD
        dECk = dE @ Ck + E @ dC
        out.append(np.block([[B2 @ dEDk @ C2, B2 @ dECk],
                             [dB @ (C2 + D22 @ EDk @ C2) + Bk @ D22 @ dEDk @ C2,
                              dA + dB @ D22 @ E @ Ck + Bk @ D22 @ dECk]]))
    return out


# ----------------------------------------------------------------------------------------------------------
# Frequency-domain evaluation with analytic gradients
# ----------------------------------------------------------------------------------------------------------

def _controller_freq(Km, dKm, pts):
    """K(pts) (nf, nu, ny) and dK_i(pts) (nfree, nf, nu, ny) from controller matrices and their derivatives."""
    Ak, Bk, Ck, Dk = Km
    nk = Ak.shape[0]
    nf = pts.size
    if nk == 0:
        K = np.broadcast_to(Dk, (nf,) + Dk.shape).astype(complex)
        dK = np.array([np.broadcast_to(d[3], (nf,) + Dk.shape) for d in dKm], dtype=complex).reshape(
            len(dKm), nf, *Dk.shape)
        return K, dK
    R = np.linalg.inv(pts[:, None, None] * np.eye(nk) - Ak)  # (nf, nk, nk); nk is small
    RB = R @ Bk
    CR = Ck @ R
    K = Ck @ RB + Dk
    dK = np.empty((len(dKm), nf) + Dk.shape, dtype=complex)
    for i, (dA, dB, dC, dD) in enumerate(dKm):
        dK[i] = dC @ RB + CR @ dA @ RB + CR @ dB + dD
    return K, dK


def _channel_eval(ch: Channel, Pf, Wf, K, dK):
    """Values and gradients (nfree, nf) of one channel at frequency points with plant responses ``Pf``."""
    nz, nw = ch.nz, ch.nw
    P11, P12 = Pf[:, :nz, :nw], Pf[:, :nz, nw:]
    P21, P22 = Pf[:, nz:, :nw], Pf[:, nz:, nw:]
    ny, nu = ch.nmeas, ch.ncon
    right = np.linalg.solve(np.eye(ny) - P22 @ K, P21)                      # (I - P22 K)^-1 P21
    leftT = np.linalg.solve(np.eye(nu) - np.swapaxes(K @ P22, 1, 2), np.swapaxes(P12, 1, 2))
    left = np.swapaxes(leftT, 1, 2)                                          # P12 (I - K P22)^-1
    T = P11 + P12 @ K @ right + ch.offset
    U, S, Vh = np.linalg.svd(T)
    if ch.mode == "max":
        k = 0
    else:
        k = min(nz, nw) - 1
    sig = S[:, k]
    u = U[:, :, k]
    v = Vh[:, k, :].conj()
    a = np.einsum("fzp,fz->fp", left.conj(), u)          # left^H u
    b = np.einsum("fyw,fw->fy", right, v)                 # right v
    dsig = np.real(np.einsum("fp,ifpq,fq->if", a.conj(), dK, b)) if dK is not None else None
    if ch.mode == "max":
        val = Wf * sig
        grad = None if dsig is None else Wf * dsig
    else:
        sig = np.maximum(sig, 1e-300)
        val = Wf / sig
        grad = None if dsig is None else -Wf * dsig / sig**2
    return val, grad


class _Problem:
    """Shared state of one optimisation: controller structure, channels and stability plants."""

    def __init__(self, structure: Structure, channels: Sequence[Channel], stab: Sequence[tuple], free,
                 scale, stab_margin=1e-6, poles=None):
        self.s, self.channels, self.stab = structure, list(channels), list(stab)
        self.free = np.asarray(free, bool)
        self.scale = np.asarray(scale, float)
        self.theta0 = structure.values
        self.stab_margin = stab_margin
        self.poles = poles  # (min_decay, min_damping) or None
        self._parts = [_partition(P, nm, nc) for P, nm, nc in self.stab]
        self.n_eig = 8
        self.soft = [c for c in self.channels if not c.hard]
        self.hardch = [c for c in self.channels if c.hard]
        if not self.soft:  # nothing to minimise but hard goals: minimise their maximum
            self.soft = self.hardch

    def theta(self, x):
        th = self.theta0.copy()
        th[self.free] = x * self.scale
        return th

    def x_of(self, theta):
        return np.asarray(theta, float)[self.free] / self.scale

    # -- stability -------------------------------------------------------------------------------------------
    def eig_terms(self, theta, grad=False):
        """Stability constraint values g >= 0 (one per closed-loop eigenvalue and plant) and their gradients."""
        gs, dgs = [], []
        Km = self.s.matrices(theta)
        dKm = self.s.matrix_derivatives(theta, self.free) if grad else None
        for (P, nmeas, ncon), part in zip(self.stab, self._parts):
            Acl = _cl_matrices(P, nmeas, ncon, *Km, part=part)[0]
            if Acl.shape[0] == 0:
                continue
            dt = float(P.dt) if lti.is_discrete(P) else 0.0
            if grad:
                lam, yl, xr = sla.eig(Acl, left=True, right=True)
            else:
                lam = np.linalg.eigvals(Acl)
            g = self._eig_g(lam, dt)
            gs.append(g)
            if grad:
                dA = _dAcl(part, Km, dKm)
                den = np.einsum("ij,ij->j", yl.conj(), xr)
                den = np.where(np.abs(den) < 1e-14, 1e-14, den)
                dlam = np.array([np.einsum("ij,ik,kj->j", yl.conj(), d, xr) / den for d in dA])  # (nfree, n)
                h = 1e-7
                # g is an explicit smooth function of lambda; differentiate it along d lambda numerically
                gp = self._eig_g(lam[None, :] + h * dlam, dt)
                dgs.append(((gp - g[None, :]) / h) * self.scale[:, None])
        g = np.concatenate(gs) if gs else np.zeros(0)
        # only the few eigenvalues nearest the boundary enter the QP (sorted values are continuous in theta);
        # this keeps the constraint count fixed and small, which is what the SLSQP cost scales with
        order = np.argsort(g)[: self.n_eig]
        if not grad:
            return g[order]
        dg = np.concatenate(dgs, axis=1) if dgs else np.zeros((self.free.sum(), 0))
        return g[order], dg[:, order]

    def _eig_g(self, lam, dt):
        lam = np.asarray(lam)
        if dt:
            g = (1.0 - self.stab_margin) - np.abs(lam)
        else:
            g = -self.stab_margin - lam.real
        if self.poles is not None:
            min_decay, min_damp = self.poles
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.log(np.where(np.abs(lam) < 1e-9, 1e-9, lam)) / dt if dt else lam
            fast = np.abs(lam) < 1e-9 if dt else np.zeros(lam.shape, bool)
            gd = np.where(fast, 1e3, -s.real - min_decay)
            gz = np.where(fast, 1e3, -s.real - min_damp * np.abs(s))
            # scale to the same order as the stability constraint
            g = np.minimum(g, np.minimum(gd, gz) * (dt if dt else 1.0))
        return g

    def stable(self, theta) -> bool:
        g = self.eig_terms(theta)
        return bool(g.size == 0 or g.min() > 0)

    # -- frequency channels ----------------------------------------------------------------------------------
    def controller_freq(self, theta, ch, w, grad):
        Km = self.s.matrices(theta)
        dKm = self.s.matrix_derivatives(theta, self.free) if grad else []
        K, dK = _controller_freq(Km, dKm, ch.points(w))
        return K, (dK if grad else None)

    def grid_values(self, theta, ch):
        K, _ = self.controller_freq(theta, ch, ch.grid, False)
        return _channel_eval(ch, ch.Pgrid, ch.Wgrid, K, None)[0]

    def point_values(self, theta, ch, w, Pf=None, grad=False):
        w = np.atleast_1d(np.asarray(w, float))
        Pf = ch.plant_at(w) if Pf is None else Pf
        K, dK = self.controller_freq(theta, ch, w, grad)
        return _channel_eval(ch, Pf, ch._weight(w), K, dK)

    def peaks(self, theta, ch, nmax=6):
        """Local maxima of the channel value over its band: grid, then bounded refinement in log frequency."""
        vals = self.grid_values(theta, ch)
        g = ch.grid
        idx = [i for i in range(len(g)) if (i == 0 or vals[i] >= vals[i - 1]) and
               (i == len(g) - 1 or vals[i] >= vals[i + 1])]
        idx = sorted(idx, key=lambda i: -vals[i])[:nmax]
        out = []
        for i in idx:
            # zoom twice on a 15-point sub-grid between the neighbours: two batched evaluations per peak
            lo, hi = np.log(g[max(i - 1, 0)]), np.log(g[min(i + 1, len(g) - 1)])
            best_v, best_w = float(vals[i]), float(g[i])
            for _ in range(2):
                wz = np.exp(np.linspace(lo, hi, 15))
                vz = self.point_values(theta, ch, wz)[0]
                k = int(np.argmax(vz))
                if vz[k] > best_v:
                    best_v, best_w = float(vz[k]), float(wz[k])
                step = (hi - lo) / 14
                lo, hi = np.log(best_w) - step, np.log(best_w) + step
            out.append((best_v, best_w))
        return sorted(out, reverse=True)

    def values(self, theta):
        """Peak value of every channel (grid + refinement): list of (value, w_peak)."""
        return [self.peaks(theta, ch, nmax=3)[0] for ch in self.channels]

    def merit(self, theta):
        """(hard violation, soft objective) at theta; (inf, inf) when not stable."""
        if not self.stable(theta):
            return np.inf, np.inf, None
        vals = self.values(theta)
        soft = max(v for (v, _), c in zip(vals, self.channels) if c in self.soft)
        hards = [v for (v, _), c in zip(vals, self.channels) if c.hard]
        viol = max([0.0] + [v - 1.0 for v in hards])
        return viol, soft, vals


def _better(a, b, tol=0.0):
    """Is merit a = (violation, objective) better than b?"""
    if a[0] > 1e-9 or b[0] > 1e-9:
        return a[0] < b[0] - 1e-9 or (abs(a[0] - b[0]) <= 1e-9 and a[1] < b[1] * (1 - tol))
    return a[1] < b[1] * (1 - tol)


def optimise(prob: _Problem, theta_start, *, max_iter=60, tol=1e-4, time_limit_s=None, lower=None, upper=None):
    """Trust-region epigraph SQP from a stabilising ``theta_start``; returns (theta, merit, history)."""
    t0 = time.perf_counter()
    x = prob.x_of(theta_start)
    lo = prob.x_of(lower) if lower is not None else np.full(x.shape, -np.inf)
    hi = prob.x_of(upper) if upper is not None else np.full(x.shape, np.inf)
    m = prob.merit(prob.theta(x))
    if not np.isfinite(m[1]):
        raise NotStabilisableError("the start does not stabilise the closed loop")
    history = [m[1]]
    active = {id(ch): [] for ch in prob.channels}
    activeP = {id(ch): [] for ch in prob.channels}

    def add_peaks(theta):
        for ch in prob.channels:
            if active[id(ch)]:  # drop active frequencies far below the current level: they never bind
                vals = prob.point_values(theta, ch, active[id(ch)], np.array(activeP[id(ch)]))[0]
                keep = vals >= 0.3 * vals.max()
                active[id(ch)] = [w for w, k in zip(active[id(ch)], keep) if k]
                activeP[id(ch)] = [p for p, k in zip(activeP[id(ch)], keep) if k]
            found = [w for _, w in prob.peaks(theta, ch)]
            if ch.exact_peak:
                wpk = lti.hinfnorm(closed_loop(ch.P, ch.nmeas, ch.ncon, prob.s.ss(theta)))[1]
                if np.isfinite(wpk):
                    found.append(min(max(wpk, ch.lo), ch.hi))
            for w in found:
                ws = active[id(ch)]
                if all(abs(np.log(w / w0)) > 1e-3 for w0 in ws):
                    ws.append(w)
                    activeP[id(ch)].append(ch.plant_at([w])[0])
            if len(active[id(ch)]) > 30:  # bound the QP size; oldest peaks are the least relevant
                active[id(ch)] = active[id(ch)][-30:]
                activeP[id(ch)] = activeP[id(ch)][-30:]

    add_peaks(prob.theta(x))
    delta = 1.0
    stall = 0
    nx = x.size
    for _ in range(max_iter):
        if time_limit_s is not None and time.perf_counter() - t0 > time_limit_s:
            break
        chans = [(ch, np.array(active[id(ch)]), np.array(activeP[id(ch)])) for ch in prob.channels]

        def cons_f(z):
            th = prob.theta(z[:nx])
            out = []
            for ch, w, Pf in chans:
                v, _ = prob.point_values(th, ch, w, Pf)
                if ch in prob.soft:
                    out.append(z[nx] - v)
                if ch.hard:
                    out.append(HARD_BOUND - v)
            out.append(prob.eig_terms(th))
            return np.concatenate(out)

        def cons_j(z):
            th = prob.theta(z[:nx])
            rows = []
            for ch, w, Pf in chans:
                _, g = prob.point_values(th, ch, w, Pf, grad=True)
                g = (g * prob.scale[:, None]).T  # (nf, nfree) in scaled variables
                if ch in prob.soft:
                    rows.append(np.hstack([-g, np.ones((g.shape[0], 1))]))
                if ch.hard:
                    rows.append(np.hstack([-g, np.zeros((g.shape[0], 1))]))
            _, dg = prob.eig_terms(th, grad=True)
            rows.append(np.hstack([dg.T, np.zeros((dg.shape[1], 1))]))
            return np.vstack(rows)

        t_start = max(v for v, c in zip([vv for vv, _ in m[2]], prob.channels) if c in prob.soft) * 1.0001
        z0 = np.r_[x, t_start]
        bnds = [(max(lo[i], x[i] - delta), min(hi[i], x[i] + delta)) for i in range(nx)] + [(0.0, None)]
        res = minimize(lambda z: z[nx], z0, jac=lambda z: np.r_[np.zeros(nx), 1.0], method="SLSQP",
                       bounds=bnds, constraints=[{"type": "ineq", "fun": cons_f, "jac": cons_j}],
                       options={"maxiter": 20, "ftol": 1e-9})
        xn = np.clip(res.x[:nx], lo, hi)
        mn = prob.merit(prob.theta(xn))
        if np.isfinite(mn[1]):
            add_peaks(prob.theta(xn))
        if _better(mn, m):
            gain = (m[1] - mn[1]) / max(m[1], 1e-12)
            hit = np.any(np.abs(xn - x) > 0.9 * delta)
            x, m = xn, mn
            delta = min(3 * delta, 100.0) if hit else delta
            stall = stall + 1 if (gain < tol and m[0] <= 1e-9) else 0
        else:
            delta *= 0.3
        history.append(m[1])
        if stall >= 3 or delta < 1e-4:
            break
    return prob.theta(x), m, history


# ----------------------------------------------------------------------------------------------------------
# hinfstruct front end
# ----------------------------------------------------------------------------------------------------------

@dataclasses.dataclass
class HinfstructResult:
    """Outcome of :func:`hinfstruct`.

    ``gamma`` is the closed-loop H-inf norm computed exactly (SLICOT ab13dd via ``rotorlab.lti.hinfnorm``)
    on the returned controller; ``starts`` holds the verified gamma of every start (inf when a start failed).
    """

    gamma: float
    controller: ct.StateSpace
    params: dict
    history: list
    starts: list
    success: bool
    structure: Structure
    w_peak: float


def _as_structure(controller, nmeas, ncon, dt) -> Structure:
    if isinstance(controller, str):
        if controller != "static":
            raise ValueError(f"controller must be 'static', a Block, a list of blocks or a Structure; got '{controller}'")
        return Structure([StaticGain(nmeas, ncon, dt=dt)])
    if isinstance(controller, Structure):
        return controller
    if isinstance(controller, Block):
        return Structure([controller])
    return Structure(list(controller))


def _random_start(prob: _Problem, theta0, rng, spread, lower, upper):
    th = theta0.copy()
    f = prob.free
    base = th[f]
    mag = np.where(np.abs(base) > 1e-12, np.abs(base), np.median(np.abs(base[np.abs(base) > 1e-12]))
                   if np.any(np.abs(base) > 1e-12) else 1.0)
    th[f] = base * np.exp(spread * rng.standard_normal(base.size)) * np.where(np.abs(base) > 1e-12, 1.0, 0.0) \
        + np.where(np.abs(base) > 1e-12, 0.0, mag * spread * rng.standard_normal(base.size))
    return np.clip(th, lower, upper)


def _stabilise(prob: _Problem, theta, lower, upper, max_iter=100):
    """Phase 1: push the closed-loop eigenvalues into the stability region (maximise the smallest margin)."""
    x = prob.x_of(theta)
    nx = x.size
    g0 = prob.eig_terms(theta)
    if g0.size == 0 or g0.min() > 0:
        return theta
    lo, hi = prob.x_of(lower), prob.x_of(upper)

    def cons_f(z):
        return prob.eig_terms(prob.theta(z[:nx])) - z[nx]

    def cons_j(z):
        _, dg = prob.eig_terms(prob.theta(z[:nx]), grad=True)
        return np.hstack([dg.T, -np.ones((dg.shape[1], 1))])

    z = np.r_[x, g0.min()]
    for _ in range(10):
        bnds = [(max(lo[i], z[i] - 1.0), min(hi[i], z[i] + 1.0)) for i in range(nx)] + [(None, 1.0)]
        res = minimize(lambda z: -z[nx], z, jac=lambda z: np.r_[np.zeros(nx), -1.0], method="SLSQP",
                       bounds=bnds, constraints=[{"type": "ineq", "fun": cons_f, "jac": cons_j}],
                       options={"maxiter": max_iter})
        z = np.r_[np.clip(res.x[:nx], lo, hi), 0.0]
        g = prob.eig_terms(prob.theta(z[:nx]))
        z[nx] = g.min()
        if g.min() > 0:
            return prob.theta(z[:nx])
    return None


_FORKED_PROBLEM = None  # set before forking workers: python-control models do not pickle


def _run_forked(args):
    return _run_start((_FORKED_PROBLEM,) + tuple(args))


def _run_start(args):
    prob, theta, lower, upper, max_iter, tol, time_limit_s = args
    th = _stabilise(prob, theta, lower, upper)
    if th is None:
        return None
    return optimise(prob, th, max_iter=max_iter, tol=tol, time_limit_s=time_limit_s, lower=lower, upper=upper)


def run_starts(prob: _Problem, theta0, lower, upper, *, starts=1, seed=0, n_jobs=1, max_iter=60, tol=1e-4,
               time_limit_s=None, spread=0.5, progress=False):
    """Optimise from ``theta0`` and ``starts - 1`` seeded random perturbations of it; list of results per start
    (None where no stabilising point was found)."""
    rng = np.random.default_rng(seed)
    thetas = [np.clip(theta0, lower, upper)] + [_random_start(prob, theta0, rng, spread, lower, upper)
                                                 for _ in range(max(starts, 1) - 1)]
    jobs = [(prob, th, lower, upper, max_iter, tol, time_limit_s) for th in thetas]
    if n_jobs and n_jobs > 1 and len(jobs) > 1 and "fork" in multiprocessing.get_all_start_methods():
        from concurrent.futures import ProcessPoolExecutor

        global _FORKED_PROBLEM
        _FORKED_PROBLEM = prob
        try:
            with ProcessPoolExecutor(max_workers=n_jobs, mp_context=multiprocessing.get_context("fork")) as ex:
                return list(ex.map(_run_forked, [j[1:] for j in jobs]))
        finally:
            _FORKED_PROBLEM = None
    from tqdm import tqdm

    return [_run_start(j) for j in tqdm(jobs, disable=not progress, desc="starts")]


def hinfstruct(P, controller, nmeas: int, ncon: int, *, starts: int = 1, seed=0, n_jobs: int = 1,
               tol: float = 1e-4, time_limit_s: float | None = None, bounds: dict | None = None,
               max_iter: int = 60, progress: bool = False) -> HinfstructResult:
    """Minimise ``||F_l(P, K(theta))||_inf`` over a fixed-structure controller subject to internal stability.

    Parameters
    ----------
    P : control.StateSpace
        Generalised plant (continuous or discrete), inputs ``[w; u]``, outputs ``[z; y]``.
    controller : "static", Block, list of Blocks or Structure
        ``"static"``: static output feedback ``u = K y`` (ncon x nmeas). Blocks combine block-diagonally;
        their inputs must add up to ``nmeas`` and outputs to ``ncon``.
    nmeas, ncon : int
        Number of measurements y (last outputs of P) and controls u (last inputs of P).
    starts : int
        Number of starts: the blocks' current values plus ``starts - 1`` seeded random perturbations.
    seed : int or numpy.random.Generator seed
    n_jobs : int
        Processes for the starts (blocks must then be picklable: no lambdas in Custom blocks).
    tol : float
        Relative objective decrease below which the iteration stops.
    time_limit_s : float, optional
        Wall-clock budget per start.
    bounds : dict, optional
        ``{"block.param": (lower, upper)}``; a parameter with lower == upper is fixed.

    Returns
    -------
    HinfstructResult
    """
    P = lti.as_ss(P)
    for tag, M in zip("ABCD", (P.A, P.B, P.C, P.D)):
        if not np.all(np.isfinite(np.asarray(M, float))):
            raise ValueError(f"the plant's {tag} matrix contains NaN or Inf")
    if not (0 < nmeas < P.noutputs and 0 < ncon < P.ninputs):
        raise ValueError(f"nmeas={nmeas}, ncon={ncon} do not fit a plant with {P.noutputs} outputs and "
                         f"{P.ninputs} inputs (P must have at least one performance input w and output z)")
    dt = float(P.dt) if lti.is_discrete(P) else 0.0
    S = _as_structure(controller, nmeas, ncon, dt)
    if S.ny != nmeas or S.nu != ncon:
        raise ValueError(f"the controller has {S.ny} inputs and {S.nu} outputs but the plant has nmeas={nmeas} "
                         f"measurements and ncon={ncon} controls")
    if (S.dt > 0) != (dt > 0) or (dt and abs(S.dt - dt) > 1e-12):
        raise ValueError(f"controller sample time {S.dt} s does not match the plant's {dt} s")
    lower = np.array([p.lower for p in S.params])
    upper = np.array([p.upper for p in S.params])
    fixed = np.array([p.fixed for p in S.params])
    names = S.names
    for name, (lo_, hi_) in (bounds or {}).items():
        if name not in names:
            raise KeyError(f"bounds name unknown parameter '{name}'; parameters are {names}")
        i = names.index(name)
        lower[i], upper[i] = lo_, hi_
        fixed[i] |= lo_ == hi_
    theta0 = np.clip(S.values, lower, upper)
    free = ~fixed
    if not free.any():
        raise ValueError("every controller parameter is fixed: nothing to tune")
    scale = np.maximum(np.abs(theta0[free]), 0.1 * max(np.max(np.abs(theta0[free])), 1.0))
    ch = Channel(P, nmeas, ncon, name="hinf", exact_peak=True)
    prob = _Problem(S, [ch], [(P, nmeas, ncon)], free, scale)
    results = run_starts(prob, theta0, lower, upper, starts=starts, seed=seed, n_jobs=n_jobs, max_iter=max_iter,
                         tol=tol, time_limit_s=time_limit_s, progress=progress)
    verified = []
    for r in results:
        if r is None:
            verified.append((np.inf, None, None, None))
            continue
        th, _, hist = r
        K = S.ss(th)
        g, wpk = lti.hinfnorm(closed_loop(P, nmeas, ncon, K))
        verified.append((g, th, hist, wpk))
    gammas = [v[0] for v in verified]
    if not np.isfinite(min(gammas)):
        raise NotStabilisableError(
            "no stabilising controller of this structure was found from any start: the plant may not be "
            "stabilisable by this structure (unstable fixed modes, or too few controller states); try more "
            "starts, a stabilising initial controller (set the block values), a higher-order block, or check "
            "that the unstable modes are controllable from u and observable from y")
    best = int(np.argmin(gammas))
    g, th, hist, wpk = verified[best]
    S.set_values(th)
    return HinfstructResult(gamma=float(g), controller=S.ss(th), params=dict(zip(names, map(float, th))),
                            history=list(map(float, hist)), starts=[float(x) for x in gammas], success=True,
                            structure=S, w_peak=float(wpk))
