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
from scipy.optimize import minimize

from rotorlab import lti
from rotorlab.tune.blocks import Block, StaticGain, Structure

__all__ = ["Channel", "HinfstructResult", "hinfstruct", "closed_loop", "optimise", "NotStabilisableError"]


# hard goals are enforced at this level inside the QP so that the verified value lands below 1 despite the
# linearisation and the finite active frequency set
HARD_BOUND = 0.995
# SLSQP iterations per trust-region subproblem. Its active frequency set is refreshed after every outer
# step anyway, so solving it to convergence (20 iterations) buys nothing: on the P2-A2 and A2-MINI/B specs
# 10 halves the callbacks and reaches the same or lower objectives.
SUBPROBLEM_ITERATIONS = 10


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
        self._akey = (self._abcd[0].tobytes(), self._abcd[0].shape, self.dt)  # channels of one plant share A
        self.grid = np.logspace(np.log10(self.lo), np.log10(self.hi), self.npoints)
        self.Pgrid = self.plant_at(self.grid)

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


def _cl_A(part, Ak, Bk, Ck, Dk):
    """Closed-loop A of ``F_l(P, K)`` alone (states: plant then controller), filled in place: the stability
    constraints need only this, at every optimiser callback."""
    A, B2, C2, D22 = part["A"], part["B2"], part["C2"], part["D22"]
    E = np.linalg.inv(np.eye(Dk.shape[0]) - Dk @ D22)
    if not np.all(np.isfinite(E)) or np.abs(E).max() > 1e12:
        raise ValueError("the interconnection is not well posed: I - Dk D22 is singular")
    EDk, ECk = E @ Dk, E @ Ck
    n, nk = A.shape[0], Ak.shape[0]
    Acl = np.empty((n + nk, n + nk))
    Acl[:n, :n] = A + B2 @ EDk @ C2
    Acl[:n, n:] = B2 @ ECk
    Acl[n:, :n] = Bk @ (C2 + D22 @ EDk @ C2)
    Acl[n:, n:] = Ak + Bk @ D22 @ ECk
    return Acl


def _cl_matrices(P, nmeas, ncon, Ak, Bk, Ck, Dk, part=None):
    p = part or _partition(P, nmeas, ncon)
    B1, C1, D11, D12, D21, D22 = p["B1"], p["C1"], p["D11"], p["D12"], p["D21"], p["D22"]
    Acl = _cl_A(p, Ak, Bk, Ck, Dk)
    E = np.linalg.inv(np.eye(ncon) - Dk @ D22)
    EDk = E @ Dk
    Bcl = np.vstack([B1 + p["B2"] @ EDk @ D21, Bk @ (D21 + D22 @ EDk @ D21)])
    Ccl = np.hstack([C1 + D12 @ EDk @ p["C2"], D12 @ E @ Ck])
    Dcl = D11 + D12 @ EDk @ D21
    return Acl, Bcl, Ccl, Dcl


def _dAcl(part, Km, dKm):
    """Exact derivatives (nfree, n, n) of the closed-loop A along the stacked controller-matrix directions
    ``dKm = (dAk, dBk, dCk, dDk)`` (each with a leading nfree axis), using ``dE = E dDk D22 E`` for
    ``E = (I - Dk D22)^-1``; one broadcast product per term instead of a loop over the parameters."""
    Ak, Bk, Ck, Dk = Km
    dA, dB, dC, dD = dKm
    B2, C2, D22 = part["B2"], part["C2"], part["D22"]
    E = np.linalg.inv(np.eye(Dk.shape[0]) - Dk @ D22)
    EDk = E @ Dk
    dE = E @ dD @ D22 @ E
    dEDk = dE @ Dk + E @ dD
    dECk = dE @ Ck + E @ dC
    top = np.concatenate([B2 @ dEDk @ C2, B2 @ dECk], axis=2)
    bot = np.concatenate([dB @ (C2 + D22 @ EDk @ C2) + Bk @ D22 @ dEDk @ C2,
                          dA + dB @ (D22 @ E @ Ck) + Bk @ D22 @ dECk], axis=2)
    return np.concatenate([top, bot], axis=1)


# ----------------------------------------------------------------------------------------------------------
# Frequency-domain evaluation with analytic gradients, batched over channels and frequencies
# ----------------------------------------------------------------------------------------------------------

def _controller_freq(Km, dKm, pts):
    """K(pts) (nf, nu, ny) and, when ``dKm`` (stacked derivative matrices) is given, dK (nfree, nf, nu, ny)."""
    Ak, Bk, Ck, Dk = Km
    nk, nf = Ak.shape[0], pts.size
    if nk == 0:
        K = np.broadcast_to(Dk, (nf,) + Dk.shape).astype(complex)
        dK = None if dKm is None else np.broadcast_to(dKm[3][:, None], (dKm[3].shape[0], nf) + Dk.shape)
        return K, dK
    if not np.any(Ak - np.diag(np.diag(Ak))):
        # diagonal A (every PID block): with r_k = 1/(z - a_k), K = sum_k r_k C[:, k] B[k, :] + D and
        # dK = sum_k r_k (dC[:, k] B[k, :] + C[:, k] dB[k, :]) + sum_kl r_k r_l C[:, k] dA[k, l] B[l, :] + dD:
        # two matrix products over all frequencies instead of stacks of tiny ones
        r = 1.0 / (pts[:, None] - np.diag(Ak)[None, :])                   # (nf, nk)
        nu, ny = Dk.shape
        K = (r @ np.einsum("uk,ky->kuy", Ck, Bk).reshape(nk, nu * ny)).reshape(nf, nu, ny) + Dk
        if dKm is None:
            return K, None
        dA, dB, dC, dD = dKm
        nfree = dA.shape[0]
        Q1 = np.einsum("iuk,ky->kiuy", dC, Bk) + np.einsum("uk,iky->kiuy", Ck, dB)
        Q2 = np.einsum("uk,ikl,ly->kliuy", Ck, dA, Bk)
        rr = (r[:, :, None] * r[:, None, :]).reshape(nf, nk * nk)
        dK = r @ Q1.reshape(nk, -1) + rr @ Q2.reshape(nk * nk, -1)
        dK = dK.reshape(nf, nfree, nu, ny).transpose(1, 0, 2, 3) + dD[:, None]
        return K, dK
    R = np.linalg.inv(pts[:, None, None] * np.eye(nk) - Ak)
    RB = R @ Bk
    CR = Ck @ R
    K = Ck @ RB + Dk
    if dKm is None:
        return K, None
    dA, dB, dC, dD = dKm
    dK = (dC[:, None] @ RB[None] + CR[None] @ dA[:, None] @ RB[None] + CR[None] @ dB[:, None]
          + dD[:, None])
    return K, dK


def _lft_values(Pf, Wf, off, is_min, K, dK, nz, nw):
    """Channel values (nf,) and gradients (nfree, nf) at stacked frequency points.

    ``T = F_l(P(jw), K(jw)) + off``; the value is ``W sigma_max(T)`` (or ``W / sigma_min(T)`` where
    ``is_min``). ``T = P11 + P12 M K P21`` with ``M = (I - K P22)^-1``; the gradient is
    ``d sigma = Re(u^H P12 M dK (I - P22 K)^-1 P21 v)`` with ``(I - P22 K)^-1 P21 = P21 + P22 M K P21``
    (push-through identity), so one small batched inverse serves values and gradients.
    """
    N = Pf.shape[0]
    P11, P12 = Pf[:, :nz, :nw], Pf[:, :nz, nw:]
    P21, P22 = Pf[:, nz:, :nw], Pf[:, nz:, nw:]
    nu = K.shape[1]
    KP21 = K @ P21
    M = np.linalg.inv(np.eye(nu) - K @ P22)
    left = P12 @ M
    T = P11 + left @ KP21 + off[:, None, None]
    if min(nz, nw) == 1:  # a vector: its only singular value is its 2-norm, no SVD needed
        sig = np.sqrt(np.sum(T.real**2 + T.imag**2, axis=(1, 2)))
        sg = np.maximum(sig, 1e-300)[:, None]
        if nw == 1:
            u, v = T[:, :, 0] / sg, np.ones((N, 1))
        else:
            u, v = np.ones((N, 1)), T[:, 0, :].conj() / sg
    else:
        U, S, Vh = np.linalg.svd(T)
        k = np.where(is_min, min(nz, nw) - 1, 0)
        ar = np.arange(N)
        sig, u, v = S[ar, k], U[ar, :, k], Vh[ar, k, :].conj()
    sig = np.maximum(sig, 1e-300)
    val = np.where(is_min, Wf / sig, Wf * sig)
    if dK is None:
        return val, None
    right = P21 + P22 @ (M @ KP21)
    a = np.einsum("fzp,fz->fp", left.conj(), u)            # left^H u
    b = np.einsum("fyw,fw->fy", right, v)                   # right v
    ab = (a.conj()[:, :, None] * b[:, None, :]).reshape(N, -1)
    dsig = np.real(np.sum(dK.reshape(dK.shape[0], N, -1) * ab[None], axis=2))
    grad = Wf * dsig
    grad[:, is_min] = -val[is_min] * dsig[:, is_min] / sig[is_min]  # d(W/sigma) = -(W/sigma) d sigma / sigma
    return val, grad


class _Points:
    """A fixed set of (channel, frequencies) requests stacked for one batched evaluation per theta.

    Channels with the same partition sizes share one stack. Plant responses are computed once here (one
    batched solve per channel, unless given), so every later evaluation costs only the controller response
    and a small LFT.
    """

    def __init__(self, channels, items, plants=None):
        self.n_items = len(items)
        ws = [np.atleast_1d(np.asarray(w, float)) for _, w in items]
        if plants is None:
            plants = self._plants(channels, items, ws)
        groups = {}
        for k, ((ci, _), w, Pf) in enumerate(zip(items, ws, plants)):
            ch = channels[ci]
            g = groups.setdefault((ch.nz, ch.nw, ch.nmeas, ch.ncon),
                                  dict(P=[], W=[], pts=[], off=[], mn=[], map=[]))
            g["P"].append(np.asarray(Pf).reshape((w.size, ch.nz + ch.nmeas, ch.nw + ch.ncon)))
            g["W"].append(ch._weight(w))
            g["pts"].append(ch.points(w))
            g["off"].append(np.full(w.size, ch.offset))
            g["mn"].append(np.full(w.size, ch.mode == "min"))
            g["map"].append((k, w.size))
        self.groups = [(nz, nw, {key: np.concatenate(g[key]) for key in ("P", "W", "pts", "off", "mn")}, g["map"])
                       for (nz, nw, _, _), g in groups.items()]

    @staticmethod
    def _plants(channels, items, ws):
        """Plant responses of every request: channels built on the same plant (same A, e.g. every goal of
        one model) share one batched solve ``(zI - A) X = [B_1 ... B_m]`` over all their frequencies."""
        plants = [None] * len(items)
        by_a = {}
        for k, (ci, _) in enumerate(items):
            by_a.setdefault(channels[ci]._akey, []).append(k)
        for ks in by_a.values():
            cis = list(dict.fromkeys(items[k][0] for k in ks))
            cols, c0 = {}, 0
            for ci in cis:
                cols[ci] = (c0, c0 + channels[ci]._abcd[1].shape[1])
                c0 = cols[ci][1]
            A = channels[cis[0]]._abcd[0]
            wall = np.concatenate([ws[k] for k in ks])
            if A.shape[0]:
                # the channels' input matrices are views of one plant's few inputs: solve for an orthonormal
                # basis of their column space only (rank 1 for the SISO cascade), then map back
                Ball = np.hstack([channels[ci]._abcd[1] for ci in cis])
                U, sv, Vt = np.linalg.svd(Ball, full_matrices=False)
                r = max(int(np.sum(sv > 1e-12 * sv[0])), 1) if sv.size and sv[0] > 0 else 1
                pts = channels[cis[0]].points(wall)
                X = np.linalg.solve(pts[:, None, None] * np.eye(A.shape[0]) - A,
                                    np.broadcast_to(U[:, :r], (wall.size, A.shape[0], r))) @ (sv[:r, None] * Vt[:r])
            i = 0
            for k in ks:
                ci, n = items[k][0], ws[k].size
                _, _, C, D = channels[ci]._abcd
                if A.shape[0]:
                    plants[k] = C @ X[i:i + n, :, cols[ci][0]:cols[ci][1]] + D
                else:
                    plants[k] = np.broadcast_to(D, (n,) + D.shape).astype(complex)
                i += n
        return plants


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
        self._stab_dt = [float(P.dt) if lti.is_discrete(P) else 0.0 for P, _, _ in self.stab]
        self.n_eig = 8
        self.is_hard = [c.hard for c in self.channels]
        # soft goals are minimised; with none, the hard goals' maximum is
        self.is_soft = [not c.hard for c in self.channels]
        if not any(self.is_soft):
            self.is_soft = [True] * len(self.channels)
        self.grid_points = _Points(self.channels, [(i, c.grid) for i, c in enumerate(self.channels)],
                                               [c.Pgrid for c in self.channels])
        self._peak_cache = (None, None)

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
        for (P, nmeas, ncon), part, dt in zip(self.stab, self._parts, self._stab_dt):
            Acl = _cl_A(part, *Km)
            if Acl.shape[0] == 0:
                continue
            if grad:
                lam, xr = np.linalg.eig(Acl)
                try:  # rows of V^-1 are the left eigenvectors scaled so that y_j^H x_j = 1
                    yh = np.linalg.inv(xr)
                except np.linalg.LinAlgError:  # defective: the derivative is unbounded there anyway
                    yh = np.linalg.pinv(xr)
            else:
                lam = np.linalg.eigvals(Acl)
            g = self._eig_g(lam, dt)
            gs.append(g)
            if grad:
                dA = _dAcl(part, Km, dKm)
                dlam = np.einsum("ji,nij->nj", yh, dA @ xr)                            # (nfree, n)
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
    def evaluate_points(self, theta, pts: _Points, grad=False):
        """Values (and gradients w.r.t. the free parameters, unscaled) of every request in ``pts``: lists in
        request order. One controller response and one LFT per channel group."""
        Km = self.s.matrices(theta)
        dKm = self.s.matrix_derivatives(theta, self.free) if grad else None
        vals, grads = [None] * pts.n_items, [None] * pts.n_items
        for nz, nw, cat, mapping in pts.groups:
            K, dK = _controller_freq(Km, dKm, cat["pts"])
            v, g = _lft_values(cat["P"], cat["W"], cat["off"], cat["mn"], K, dK, nz, nw)
            i = 0
            for k, n in mapping:
                vals[k] = v[i:i + n]
                if grad:
                    grads[k] = g[:, i:i + n]
                i += n
        return vals, grads

    def all_peaks(self, theta, nmax=6):
        """Local maxima of every channel's value over its band, each channel's list sorted by value: dense
        grid, then two 15-point zooms around every peak, all channels and peaks in one batch per stage."""
        key = (np.asarray(theta, float).tobytes(), nmax)
        if self._peak_cache[0] == key:  # merit and the active-set update ask for the same point
            return self._peak_cache[1]
        vals = self.evaluate_points(theta, self.grid_points)[0]
        cand = []  # (channel, log lo, log hi, grid value, grid w)
        for ci, (ch, v) in enumerate(zip(self.channels, vals)):
            g = ch.grid
            is_pk = np.r_[True, v[1:] >= v[:-1]] & np.r_[v[:-1] >= v[1:], True]
            idx = np.flatnonzero(is_pk)
            # peaks below 0.3 x the channel's maximum never bind (the active-set update drops them too)
            idx = idx[v[idx] >= 0.3 * v.max()]
            idx = idx[np.argsort(-v[idx], kind="stable")][:nmax]
            for i in idx:
                cand.append((ci, np.log(g[max(i - 1, 0)]), np.log(g[min(i + 1, len(g) - 1)]), v[i], g[i]))
        ci_c, lo, hi, best_v, best_w = (np.array(c) for c in zip(*cand))
        ci_c = ci_c.astype(int)
        frac = np.linspace(0.0, 1.0, 15)
        for _ in range(2):
            wz = np.exp(lo[:, None] + (hi - lo)[:, None] * frac)                     # (ncand, 15)
            # one request per channel (all its peaks' sub-grids), split back per peak
            chs = np.unique(ci_c)
            req = [(c, wz[ci_c == c].ravel()) for c in chs]
            vals = self.evaluate_points(theta, _Points(self.channels, req))[0]
            vz = np.empty_like(wz)
            for c, v in zip(chs, vals):
                vz[ci_c == c] = v.reshape(-1, frac.size)
            k = np.argmax(vz, axis=1)
            vk, wk = vz[np.arange(len(k)), k], wz[np.arange(len(k)), k]
            up = vk > best_v
            best_v, best_w = np.where(up, vk, best_v), np.where(up, wk, best_w)
            step = (hi - lo) / 14
            lo, hi = np.log(best_w) - step, np.log(best_w) + step
        cand = zip(ci_c, lo, hi, best_v, best_w)
        out = [[] for _ in self.channels]
        for ci, _, _, v, w in cand:
            out[ci].append((float(v), float(w)))
        out = [sorted(o, reverse=True) for o in out]
        self._peak_cache = (key, out)
        return out

    def values(self, theta):
        """Peak value of every channel (grid + refinement): list of (value, w_peak)."""
        return [p[0] for p in self.all_peaks(theta)]

    def merit(self, theta):
        """(hard violation, soft objective) at theta; (inf, inf) when not stable."""
        if not self.stable(theta):
            return np.inf, np.inf, None
        vals = self.values(theta)
        soft = max(v for (v, _), s in zip(vals, self.is_soft) if s)
        viol = max([0.0] + [v - 1.0 for (v, _), h in zip(vals, self.is_hard) if h])
        return viol, soft, vals


def _better(a, b, tol=0.0):
    """Is merit a = (violation, objective) better than b?"""
    if a[0] > 1e-9 or b[0] > 1e-9:
        return a[0] < b[0] - 1e-9 or (abs(a[0] - b[0]) <= 1e-9 and a[1] < b[1] * (1 - tol))
    return a[1] < b[1] * (1 - tol)


class _Subproblem:
    """Constraint values and Jacobian of one trust-region SLSQP solve over a fixed active frequency set.

    SLSQP asks for the constraint values and their Jacobian in separate callbacks at the same point; both
    come from one batched evaluation here, cached by the point.
    """

    def __init__(self, prob: _Problem, active, activeP):
        self.prob = prob
        self.nx = int(prob.free.sum())
        self.chans = [ci for ci in range(len(prob.channels)) if len(active[ci])]
        self.pts = _Points(prob.channels, [(ci, active[ci]) for ci in self.chans],
                                       [np.array(activeP[ci]) for ci in self.chans])
        self._key = None

    def _eval(self, z):
        key = z[:self.nx].tobytes()
        if key == self._key:
            return self._val
        prob, nx = self.prob, self.nx
        th = prob.theta(z[:nx])
        vals, grads = prob.evaluate_points(th, self.pts, grad=True)
        g_eig, dg_eig = prob.eig_terms(th, grad=True)
        rows_v, rows_j = [], []
        for ci, v, g in zip(self.chans, vals, grads):
            g = (g * prob.scale[:, None]).T  # (nf, nfree) in scaled variables
            if prob.is_soft[ci]:
                rows_v.append((1.0, 0.0, v))       # t - v
                rows_j.append(np.hstack([-g, np.ones((g.shape[0], 1))]))
            if prob.is_hard[ci]:
                rows_v.append((0.0, HARD_BOUND, v))  # HARD_BOUND - v
                rows_j.append(np.hstack([-g, np.zeros((g.shape[0], 1))]))
        rows_j.append(np.hstack([dg_eig.T, np.zeros((dg_eig.shape[1], 1))]))
        self._key, self._val = key, (rows_v, g_eig, np.vstack(rows_j))
        return self._val

    def fun(self, z):
        rows_v, g_eig, _ = self._eval(z)
        return np.concatenate([a * z[self.nx] + b - v for a, b, v in rows_v] + [g_eig])

    def jac(self, z):
        return self._eval(z)[2]


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
    nch = len(prob.channels)
    active = [[] for _ in range(nch)]
    activeP = [[] for _ in range(nch)]

    def add_peaks(theta):
        held = [ci for ci in range(nch) if active[ci]]
        if held:  # drop active frequencies far below the current level: they never bind
            pts = _Points(prob.channels, [(ci, active[ci]) for ci in held],
                                      [np.array(activeP[ci]) for ci in held])
            for ci, vals in zip(held, prob.evaluate_points(theta, pts)[0]):
                keep = vals >= 0.3 * vals.max()
                active[ci] = [w for w, k in zip(active[ci], keep) if k]
                activeP[ci] = [p for p, k in zip(activeP[ci], keep) if k]
        peaks = prob.all_peaks(theta)
        for ci, ch in enumerate(prob.channels):
            found = [w for _, w in peaks[ci]]
            if ch.exact_peak:
                wpk = lti.hinfnorm(closed_loop(ch.P, ch.nmeas, ch.ncon, prob.s.ss(theta)))[1]
                if np.isfinite(wpk):
                    found.append(min(max(wpk, ch.lo), ch.hi))
            new = []
            for w in found:
                if all(abs(np.log(w / w0)) > 1e-3 for w0 in active[ci] + new):
                    new.append(w)
            if new:
                active[ci] += new
                activeP[ci] += list(ch.plant_at(new))
            if len(active[ci]) > 30:  # bound the QP size; oldest peaks are the least relevant
                active[ci] = active[ci][-30:]
                activeP[ci] = activeP[ci][-30:]

    add_peaks(prob.theta(x))
    delta = 1.0
    stall = 0
    nx = x.size
    for _ in range(max_iter):
        if time_limit_s is not None and time.perf_counter() - t0 > time_limit_s:
            break
        sub = _Subproblem(prob, active, activeP)
        t_start = max(v for (v, _), s in zip(m[2], prob.is_soft) if s) * 1.0001
        z0 = np.r_[x, t_start]
        bnds = [(max(lo[i], x[i] - delta), min(hi[i], x[i] + delta)) for i in range(nx)] + [(0.0, None)]
        res = minimize(lambda z: z[nx], z0, jac=lambda z: np.r_[np.zeros(nx), 1.0], method="SLSQP",
                       bounds=bnds, constraints=[{"type": "ineq", "fun": sub.fun, "jac": sub.jac}],
                       options={"maxiter": SUBPROBLEM_ITERATIONS, "ftol": 1e-9})
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
