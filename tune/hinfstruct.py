"""Structured (fixed-order, fixed-structure) H-inf synthesis, in the spirit of Apkarian & Noll (2006),
MATLAB's ``hinfstruct`` / ``systune`` and HIFOO / HANSO (Burke, Lewis, Overton).

The problem ``min_theta ||F_l(P, K(theta))||_inf`` subject to internal stability is non-convex and
non-smooth: the norm is a maximum over frequency of the largest singular value. Every start runs two phases.

Stabilisation. The spectral abscissa of the closed loop (spectral radius - 1 when discrete; pole-region terms
included when the caller asks for them) is minimised by nonsmooth BFGS with weak Wolfe steps, with no step
cap, until it is negative, with random restarts of the size of the best point; where that ends far larger than
the start (the abscissa can keep falling slowly along a high-gain direction), random points of the start's size
are stabilised too and the smallest stable point is kept. A start that cannot stabilise
reports the minimised abscissa and a certificate: unstable modes that no controller of the structure moves
(PBH rank test on the plant, or an eigenvalue shared by the closed loops of random controllers).
:class:`NotStabilisableError` is raised only with such a certificate; otherwise :class:`StabilisationError`
says what was tried and how far it got.

Optimisation: a hybrid, alternated in rounds until a whole round gains less than ``tol``:

1. the tangent program of Apkarian & Noll over the full active set of peak frequencies (every local maximum
   of each channel on a dense grid refined by zooming, the exact ab13dd peak, and the frequencies of the
   closed-loop modes, where lightly damped resonances narrower than the grid spacing peak)::

       minimise t  s.t.  sigma_max(W(w_i) T(theta, j w_i)) <= t   for the active frequencies w_i
                         closed-loop eigenvalues inside the stability region

   solved by SLSQP inside a box trust region with analytic gradients of the singular values
   (``d sigma = Re(u^H dT v)``, ``dT = P12 (I - K P22)^-1 dK (I - P22 K)^-1 P21``) and of the eigenvalues
   (``d lambda = y^H dA x / y^H x``); steps are accepted only when the objective re-evaluated on the whole
   axis decreases, and the active set is refreshed after every step. Its stopping test is a stationarity
   measure: the decrease the tangent program predicts over all active frequencies, relative to gamma, which is
   zero exactly when zero lies in the convex hull of the active gradients (Clarke stationarity of the max
   function), not a count of small steps;
2. BFGS on the nonsmooth objective (the exact ab13dd norm, gradient at its peak) with the weak Wolfe line
   search of Lewis & Overton, stopped by HANSO's test (the smallest vector in the convex hull of the
   gradients at the nearby recent iterates), a failed line search, or a stalled window;
3. gradient sampling from where BFGS stopped (HANSO's second phase, Burke, Lewis & Overton 2005), with a
   BFGS metric and the reuse of earlier samples of Curtis & Que (2013): the gradients at ``n + 1`` random
   points in a ball around x and at x itself; the smallest vector of their convex hull (in the BFGS metric)
   gives a direction that lowers every nearby piece of the max function at once; Armijo backtracking; the
   ball shrinks (1e-3 to 1e-6 relative) when the hull holds a vector shorter than ``tol`` (approximate
   Clarke stationarity), when no step decreases, or when progress stalls.

Why a hybrid: the tangent program uses the frequency structure (many peaks of equal height at the optimum
of a MIMO or lightly damped problem, where a single-gradient method zig-zags) and certifies stationarity,
but restarts its curvature model every outer step and linearises each peak at a fixed frequency, which
misjudges a resonance that is narrower than the step moves it; BFGS accumulates curvature across steps and
descends along non-smooth valleys, but a single gradient cannot certify or escape a kink where several
peaks are active, so at such points it creeps (on COMPleib's HE3, about 1e-5 per iteration beside a
closed-loop mode damped to 2e-4, where Nelder-Mead still descended). Gradient sampling is what HANSO
uses there: it needs no knowledge of which peaks are active, only gradients near x, and it converges to
Clarke-stationary points with probability one; its cost, ``n + 1`` exact norms per step, is paid only after
BFGS has stopped (benchmarks/bench_hinfstruct.py and benchmarks/compleib.py have the numbers; the cascade
tuner, whose objective is a grid search over ten goals, skips it to keep a start under a second).

Units. hinfstruct searches on the plant in its own units (:class:`_PlantUnits`), never in the caller's units, a
fixed size or the start's: control ``i`` measured in ``gu_i`` and measurement ``j`` in ``gy_j``, sizes fitted to the
log-magnitude of ``P22`` at the frequencies where the open-loop performance is large (:func:`_plant_units`), so that a
parameter that carries the units of the plant's signals (static gains, PID gains, B, C, D of state-space blocks,
:meth:`rotorlab.tune.blocks.Block.io_exponents`) is measured in ``1 / (gu_i gy_j)``; time constants and the like keep
a unit of their own. The entries of that plant which the units touch are rounded to :data:`SNAP_BITS` significant bits.
Rescaling any control or measurement of P by a positive factor, with the controller mapped back, then gives the same
plant, start and variables bit for bit, not merely to round-off: the whole seeded search (starts, sweep, hops, stopping
tests) runs the same arithmetic and ends at the same controller, mapped back to the caller's units
(tests/test_tune_hinfstruct_scaling.py checks every problem of benchmarks/bench_hinf_scaling.py in six units each
way). Without the rounding, round-off alone sent HE3's default search to end points up to 2.4 % apart. Between CPUs, whose
SIMD kernels round differently, a run can still split at one decision into another local minimum
(docs/hinfstruct-units.md). The stopping tests are relative to gamma and to the iterate's size
(:func:`relative_slope`), so they do not depend on a constant factor of the performance channels either. Random
starts are random controllers in those variables whose rms size is drawn log-uniformly over the loop gains at which
the normalised ``P22`` crosses 1 in the band of the plant's modes (at least three decades, up to 1000 units:
:func:`_variable_scale`), each made stabilising by phase one, and run through the project's executor. By default
:func:`hinfstruct` runs several starts and then basin hopping from the best end point (:func:`_hop`): where two runs
split at one decision into different local minima, the hops take both on towards the lower one. Where the plant makes
loop gains plausible beyond the random starts' largest size, a gain-scale sweep (:func:`_scale_sweep`) runs between
the starts and the hops: size by size on a log grid over those decades, seeded directions (rank one on static gains)
screened by their exact norm and the best minimised on that size's sphere, then a few starts from the lowest, for
optima that stabilise only in a thin band of gain scale. The cascade tuner calls :func:`run_starts` on its own
variables and neither sweeps nor hops.

The same engine, stabilisation phase, starts and executor serve several weighted channels at once (soft
goals minimised, hard goals kept <= 1 and pole regions as constraints), which is how
:func:`rotorlab.tune.goals.tune_cascade` (``rotorlab tune``, the pipeline) tunes the cascade against
systune-like goals. There the tangent program carries the hard goals as constraints, and the BFGS phase
minimises the exact penalty ``soft + PENALTY * max(0, hard - bound)`` (its end point is kept only when it is
no worse in (violation, objective)); the only setting that differs is the SLSQP budget per tangent-program
subproblem (:data:`SPEC_SUB_ITER`), a smaller budget that bounds each start's cost (benchmarks/bench_tune.py
times a start).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import control as ct
import numpy as np
from scipy.optimize import lsq_linear, minimize, minimize_scalar, nnls

from rotorlab import lti
from rotorlab.executor import map_tasks, task_seeds
from rotorlab.tune.blocks import Block, StaticGain, Structure

__all__ = ["Channel", "HinfstructResult", "hinfstruct", "closed_loop", "NotStabilisableError",
           "StabilisationError", "StartFailure", "run_starts", "relative_slope"]


# hard goals are enforced at this level inside the QP so that the verified value lands below 1 despite the
# linearisation and the finite active frequency set
HARD_BOUND = 0.995
# SLSQP iterations per tangent-program subproblem. Its active frequency set is refreshed after every outer step
# anyway; on hinfstruct's hard problems (one channel, many equal peaks) solving it further pays, on the cascade
# specs (ten goals, 5-9 parameters, most SLSQP callbacks spent in its line search) 5 reaches the same or lower
# objectives than 10 or 60 at a fraction of the callbacks (benchmarks/bench_tune.py).
HYBRID_SUB_ITER = 60
SPEC_SUB_ITER = 5
# iterations per round of the hybrid optimiser: tangent-program steps, then at least this many BFGS steps
SQP_ROUND = 30
BFGS_ROUND = 100
# tangent-program steps after which a violation of the hard goals that shrank by less than 20 % ends the round
INFEASIBLE_WINDOW = 8
# exact-penalty weight of hard-goal violations in the BFGS phase (above the Lagrange multipliers of the
# cascade specs, whose goals are normalised to 1)
PENALTY = 10.0
# gradient-sampling radii (relative to the rms size of the scaled variables) and iterations per round
GS_RADII = (1e-3, 1e-4, 1e-5, 1e-6)
GS_ROUND = 300
# peaks within this fraction of gamma count as active in the reported stationarity (HinfstructResult.slope)
SLOPE_BAND = 1e-3
# hinfstruct's default search: starts (the blocks' values, then random controllers over the plant's loop-gain
# decades), then rounds of basin hopping from the best end point (:func:`_hop`): hops per round at these rms
# distances relative to the end point's size in the scaled variables, ended after HOP_PATIENCE rounds in a row
# that lower gamma by less than HOP_GAIN (relative), or after HOP_ROUNDS rounds. A round that finds another basin
# gains percents; on a problem where every run creeps (COMPleib HE3) each round gains a little by creeping
# further, which HOP_GAIN does not count as progress, so the cost stays bounded
DEFAULT_STARTS = 4
DEFAULT_HOPS = 4
HOP_SIZES = (0.03, 0.1, 0.3, 1.0)
HOP_PATIENCE = 2
HOP_GAIN = 1e-3
HOP_ROUNDS = 6
# the gain-scale sweep (:func:`_scale_sweep`), run by hinfstruct where the plant makes loop gains plausible beyond
# the random starts' largest size (10**START_TOP units): sizes on a log grid of step SWEEP_STEP decades from
# SWEEP_BELOW decades under that cap to SWEEP_ABOVE decades over the plant's top, SWEEP_DIRECTIONS directions screened
# by their exact norm at every size, the SWEEP_REFINE best of each size minimised on its sphere, and the SWEEP_STARTS
# best of those started (their size optimised first, then one start of the hybrid optimiser each)
START_TOP = 3.0
SWEEP_STEP = 0.05
SWEEP_BELOW = 0.5
SWEEP_ABOVE = 0.3
SWEEP_DIRECTIONS = 2000
SWEEP_REFINE = 3
SWEEP_STARTS = 4
# hinfstruct searches on the plant in its own units (:class:`_PlantUnits`), with the entries that carry the units of
# the controls and measurements rounded to this many significant bits: the same plant written in other units then
# gives the same numbers rather than numbers a few 1e-16 apart, which a nonsmooth search among many nearby local
# minima turns into end points up to 2.4 % apart (COMPleib HE3 over 13 rescalings). The rounding moves an entry by at
# most 6e-8 relative, far below the stopping tolerance, and gamma is recomputed on the caller's plant at the end
SNAP_BITS = 24


class NotStabilisableError(ValueError):
    """No controller of the given structure stabilises the plant, with a certificate: an unstable closed-loop
    mode that no controller of the structure moves."""


class StabilisationError(ValueError):
    """No stabilising controller was found, without a proof that none exists (the message says what was
    tried and the smallest spectral abscissa reached)."""


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
    """Lower LFT ``F_l(P, K)`` as a StateSpace (states: plant then controller), with ``u = K y``.

    Parameters
    ----------
    P : StateSpace
        Generalised plant, inputs ``[w; u]``, outputs ``[z; y]``.
    nmeas, ncon : int
        Sizes of ``y`` (the last outputs) and ``u`` (the last inputs).
    K : StateSpace
        Controller ``y -> u`` in the time domain of ``P``.

    Returns
    -------
    StateSpace
        ``w -> z``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> P = ct.ss([[1.0]], [[1.0, 1.0]], [[1.0], [1.0]], [[0.0, 0.0], [0.0, 0.0]])   # [w, u] -> [z, y], x' = x + w + u
    >>> cl = tune.closed_loop(P, 1, 1, ct.ss([], [], [], [[-3.0]]))                   # u = -3 y
    >>> print(cl.poles())
    [-2.+0.j]
    """
    P = lti.as_ss(P)
    K = lti.as_ss(K)
    mats = _cl_matrices(P, nmeas, ncon, *(np.asarray(M, float) for M in (K.A, K.B, K.C, K.D)))
    return ct.ss(*mats, P.dt)


def _partition(P, nmeas, ncon):
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    nz, nw = C.shape[0] - nmeas, B.shape[1] - ncon
    return dict(A=A, B1=B[:, :nw], B2=B[:, nw:], C1=C[:nz], C2=C[nz:], D11=D[:nz, :nw], D12=D[:nz, nw:],
                D21=D[nz:, :nw], D22=D[nz:, nw:], D22zero=not np.any(D[nz:, nw:]))


def _lft_E(part, Dk):
    """``E = (I - Dk D22)^-1`` and ``E Dk``. With ``D22 = 0`` (every strictly proper u -> y path) E is the
    identity and no inverse is formed (the products below are then exact, so the values are the same)."""
    if part["D22zero"]:
        return None, Dk
    E = np.linalg.inv(np.eye(Dk.shape[0]) - Dk @ part["D22"])
    if not np.all(np.isfinite(E)) or np.abs(E).max() > 1e12:
        raise ValueError("the interconnection is not well posed: I - Dk D22 is singular")
    return E, E @ Dk


def _cl_A(part, Ak, Bk, Ck, Dk):
    """Closed-loop A of ``F_l(P, K)`` alone (states: plant then controller), filled in place: the stability
    constraints need only this, at every optimiser callback."""
    A, B2, C2, D22 = part["A"], part["B2"], part["C2"], part["D22"]
    E, EDk = _lft_E(part, Dk)
    n, nk = A.shape[0], Ak.shape[0]
    Acl = np.empty((n + nk, n + nk))
    Acl[:n, :n] = A + B2 @ EDk @ C2
    if E is None:
        Acl[:n, n:] = B2 @ Ck
        Acl[n:, :n] = Bk @ C2
        Acl[n:, n:] = Ak
        return Acl
    ECk = E @ Ck
    Acl[:n, n:] = B2 @ ECk
    Acl[n:, :n] = Bk @ (C2 + D22 @ EDk @ C2)
    Acl[n:, n:] = Ak + Bk @ D22 @ ECk
    return Acl


def _cl_matrices(P, nmeas, ncon, Ak, Bk, Ck, Dk, part=None, Acl=None):
    """Closed-loop (A, B, C, D) of ``F_l(P, K)``; ``Acl`` when the caller already has it (same K)."""
    p = part or _partition(P, nmeas, ncon)
    B1, C1, D11, D12, D21, D22 = p["B1"], p["C1"], p["D11"], p["D12"], p["D21"], p["D22"]
    if Acl is None:
        Acl = _cl_A(p, Ak, Bk, Ck, Dk)
    E, EDk = _lft_E(p, Dk)
    if E is None:
        Bcl = np.vstack([B1 + p["B2"] @ EDk @ D21, Bk @ D21])
        Ccl = np.hstack([C1 + D12 @ EDk @ p["C2"], D12 @ Ck])
    else:
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
    if part["D22zero"]:  # E = I, dE = 0
        return np.concatenate([np.concatenate([B2 @ dD @ C2, B2 @ dC], axis=2),
                               np.concatenate([dB @ C2, dA], axis=2)], axis=1)
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


def _lft_values(Pf, Wf, off, is_min, K, nz, nw):
    """Channel values (nf,) at stacked frequency points, and what :func:`_lft_grad` needs for their gradients.

    ``T = F_l(P(jw), K(jw)) + off``; the value is ``W sigma_max(T)`` (or ``W / sigma_min(T)`` where
    ``is_min``). ``T = P11 + P12 M K P21`` with ``M = (I - K P22)^-1``; the gradient is
    ``d sigma = Re(u^H P12 M dK (I - P22 K)^-1 P21 v)`` with ``(I - P22 K)^-1 P21 = P21 + P22 M K P21``
    (push-through identity), so one small batched inverse and one SVD serve values and gradients.
    """
    N = Pf.shape[0]
    P11, P12 = Pf[:, :nz, :nw], Pf[:, :nz, nw:]
    P21, P22 = Pf[:, nz:, :nw], Pf[:, nz:, nw:]
    nu = K.shape[1]
    KP21 = K @ P21
    M = _small_inv(np.eye(nu) - K @ P22)
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
    return val, (left, u, v, M, KP21, sig, val)


def _lft_grad(Pf, Wf, is_min, ctx, dK, nz, nw):
    """Gradients (nfree, nf) of the values :func:`_lft_values` returned with ``ctx``, along ``dK``."""
    N = Pf.shape[0]
    P21, P22 = Pf[:, nz:, :nw], Pf[:, nz:, nw:]
    left, u, v, M, KP21, sig, val = ctx
    right = P21 + P22 @ (M @ KP21)
    a = np.einsum("fzp,fz->fp", left.conj(), u)            # left^H u
    b = np.einsum("fyw,fw->fy", right, v)                   # right v
    ab = (a.conj()[:, :, None] * b[:, None, :]).reshape(N, -1)
    dsig = np.real(np.sum(dK.reshape(dK.shape[0], N, -1) * ab[None], axis=2))
    grad = Wf * dsig
    grad[:, is_min] = -val[is_min] * dsig[:, is_min] / sig[is_min]  # d(W/sigma) = -(W/sigma) d sigma / sigma
    return grad


def _small_inv(X):
    """Inverse of a stack (N, n, n) of small matrices. For n <= 2 (the cascade's two controls, every SISO loop)
    by the explicit formula: numpy's batched inverse calls LAPACK once per matrix, which costs more than the
    arithmetic here and made it the largest single item of a cascade start."""
    n = X.shape[-1]
    if n == 1:
        return 1.0 / X
    if n == 2:
        a, b, c, d = X[..., 0, 0], X[..., 0, 1], X[..., 1, 0], X[..., 1, 1]
        det = a * d - b * c
        return np.stack([np.stack([d, -b], -1), np.stack([-c, a], -1)], -2) / det[..., None, None]
    return np.linalg.inv(X)


class _Points:
    """A fixed set of (channel, frequencies) requests stacked for one batched evaluation per theta.

    Channels with the same partition sizes share one stack. Plant responses are computed once here (one
    batched solve per channel, unless given), so every later evaluation costs only the controller response
    and a small LFT.
    """

    def __init__(self, channels, items, plants=None, basis=None):
        self.n_items = len(items)
        ws = [np.atleast_1d(np.asarray(w, float)) for _, w in items]
        if plants is None:
            plants = self._plants(channels, items, ws, {} if basis is None else basis)
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
    def _plants(channels, items, ws, basis):
        """Plant responses of every request: channels built on the same plant (same A, e.g. every goal of
        one model) share one batched solve ``(zI - A) X = [B_1 ... B_m]`` over all their frequencies.
        ``basis`` caches the column bases by the tuple of channel indices (the owner's channel list)."""
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
                # basis of their column space only (rank 1 for the SISO cascade), then map back; the basis is
                # kept for the next request of the same channels (the peak search asks for new frequencies at
                # every evaluation)
                key = tuple(cis)
                if key not in basis:
                    Ball = np.hstack([channels[ci]._abcd[1] for ci in cis])
                    U, sv, Vt = np.linalg.svd(Ball, full_matrices=False)
                    r = max(int(np.sum(sv > 1e-12 * sv[0])), 1) if sv.size and sv[0] > 0 else 1
                    basis[key] = (U[:, :r], sv[:r, None] * Vt[:r], np.eye(A.shape[0]))
                Ur, SV, eye = basis[key]
                pts = channels[cis[0]].points(wall)
                X = np.linalg.solve(pts[:, None, None] * eye - A,
                                    np.broadcast_to(Ur, (wall.size,) + Ur.shape)) @ SV
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
                 scale, stab_margin=1e-6, poles=None, relative_stop=False, start_decades=(-1.5, 1.5), theta0=None):
        self.s, self.channels, self.stab = structure, list(channels), list(stab)
        self.free = np.asarray(free, bool)
        self.scale = np.asarray(scale, float)
        # stopping tests relative to the iterate's size and the objective (hinfstruct: gamma is in the units of
        # the plant's w and z); the cascade's goals are normalised to 1 and its variables relative to its
        # initial gains, where the tests keep their absolute form
        self.relative_stop = bool(relative_stop)
        # the range of random starts' rms size in the scaled variables, log10 (hinfstruct: from the plant)
        self.start_decades = tuple(start_decades)
        # the tangent program keeps the closed-loop eigenvalues this much inside the stability test's own margin:
        # its solutions land on their constraints, where the test would otherwise be decided by round-off (and
        # another CPU's kernels could take another path)
        self.qp_margin = stab_margin if relative_stop else 0.0
        # the fixed parameters' values (the structure's own unless given: hinfstruct's are in the plant's units)
        self.theta0 = structure.values if theta0 is None else np.array(theta0, float)
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
        self._basis = {}
        self.grid_points = self.points([(i, c.grid) for i, c in enumerate(self.channels)],
                                       [c.Pgrid for c in self.channels])
        self._peak_cache = (None, None)
        self._exact_cache = {}
        self._cl_cache = {}
        c0 = self.channels[0]
        # one plain H-inf channel (hinfstruct): its objective is the exact ab13dd norm
        self.exact = (len(self.channels) == 1 and c0.exact_peak and c0.weight is None and c0.offset == 0.0
                      and c0.mode == "max" and not c0.hard and poles is None)
        self._exact_part = _partition(c0.P, c0.nmeas, c0.ncon) if self.exact else None
        # the stability plant that is the exact channel's own (hinfstruct's only one): its closed-loop A and
        # eigenvalues serve the norm and the mode frequencies too
        self._exact_stab = None
        if self.exact:
            same = [k for k, (part, dt) in enumerate(zip(self._parts, self._stab_dt))
                    if dt == c0.dt and all(np.array_equal(part[key], self._exact_part[key]) for key in part)]
            self._exact_stab = same[0] if same else None

    def __getstate__(self):
        d = self.__dict__.copy()
        d["_peak_cache"] = (None, None)
        d["_exact_cache"] = {}
        d["_cl_cache"] = {}
        return d

    def points(self, items, plants=None) -> _Points:
        """A :class:`_Points` request over this problem's channels (sharing its plant-basis cache)."""
        return _Points(self.channels, items, plants, basis=self._basis)

    def _closed_loops(self, theta, Km):
        """Closed-loop A of every stability plant at theta, and their eigenvalues once asked for
        (``lam`` entry, None until then); the last few points are cached: the stability test, the norm,
        the mode frequencies, the constraint values and then their Jacobian all ask for the same point."""
        key = np.asarray(theta, float).tobytes()
        hit = self._cl_cache.get(key)
        if hit is None:
            hit = {"A": [_cl_A(part, *Km) for part in self._parts], "lam": None}
            if len(self._cl_cache) >= 8:
                self._cl_cache.pop(next(iter(self._cl_cache)))
            self._cl_cache[key] = hit
        return hit

    def _eigvals(self, theta, Km=None):
        """Closed-loop eigenvalues of every stability plant at theta (cached with the closed-loop A)."""
        hit = self._closed_loops(theta, self.matrices(theta)[0] if Km is None else Km)
        if hit["lam"] is None:
            hit["lam"] = [np.linalg.eigvals(Acl) if Acl.shape[0] else np.zeros(0) for Acl in hit["A"]]
        return hit["lam"]

    def exact_peak(self, theta):
        """(H-inf norm, peak frequency rad/s) of the first channel's closed loop by ab13dd (rotorlab.lti), for
        a stabilising theta (every caller has checked stability on the same closed-loop A). The last few
        points are cached: the merit, the BFGS objective and the tangent program's active set ask for the
        same point in turn."""
        key = np.asarray(theta, float).tobytes()
        hit = self._exact_cache.get(key)
        if hit is None:
            ch = self.channels[0]
            Km = self.matrices(theta)[0]
            Acl = None if self._exact_stab is None else self._closed_loops(theta, Km)["A"][self._exact_stab]
            mats = _cl_matrices(ch.P, ch.nmeas, ch.ncon, *Km, part=self._exact_part, Acl=Acl)
            g, w = lti.hinfnorm_stable(*mats, ch.dt, tols=(1e-8,))
            hit = (g, (w if np.isfinite(w) else ch.lo))
            if len(self._exact_cache) >= 8:
                self._exact_cache.pop(next(iter(self._exact_cache)))
            self._exact_cache[key] = hit
        return hit

    def matrices(self, theta, grad=False):
        """Controller matrices (and their derivatives along the free parameters when ``grad``) at theta; the
        Structure caches both for the last point, which the channel values and stability terms share."""
        return self.s.matrices(theta), (self.s.matrix_derivatives(theta, self.free) if grad else None)

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
        Km, dKm = self.matrices(theta, grad)
        cl = self._closed_loops(theta, Km)
        lams = None if grad else self._eigvals(theta, Km)
        for k, (part, dt) in enumerate(zip(self._parts, self._stab_dt)):
            Acl = cl["A"][k]
            if Acl.shape[0] == 0:
                continue
            if grad:
                lam, xr = np.linalg.eig(Acl)
                try:  # rows of V^-1 are the left eigenvectors scaled so that y_j^H x_j = 1
                    yh = np.linalg.inv(xr)
                except np.linalg.LinAlgError:  # defective: the derivative is unbounded there anyway
                    yh = np.linalg.pinv(xr)
            else:
                lam = lams[k]
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
        vals, ctx = self.point_values(theta, pts)
        return vals, (self.point_grads(theta, pts, ctx) if grad else None)

    def point_values(self, theta, pts: _Points):
        """Values of every request in ``pts`` (list in request order) and the per-group context from which
        :meth:`point_grads` completes their gradients without a second LFT or SVD."""
        Km = self.matrices(theta)[0]
        vals, ctx = [None] * pts.n_items, []
        for nz, nw, cat, mapping in pts.groups:
            K, _ = _controller_freq(Km, None, cat["pts"])
            v, c = _lft_values(cat["P"], cat["W"], cat["off"], cat["mn"], K, nz, nw)
            ctx.append(c)
            i = 0
            for k, n in mapping:
                vals[k] = v[i:i + n]
                i += n
        return vals, ctx

    def point_grads(self, theta, pts: _Points, ctx):
        """Gradients (nfree, nf) of the values :meth:`point_values` returned with ``ctx`` at the same theta."""
        Km, dKm = self.matrices(theta, True)
        grads = [None] * pts.n_items
        for (nz, nw, cat, mapping), c in zip(pts.groups, ctx):
            _, dK = _controller_freq(Km, dKm, cat["pts"])
            g = _lft_grad(cat["P"], cat["W"], cat["mn"], c, dK, nz, nw)
            i = 0
            for k, n in mapping:
                grads[k] = g[:, i:i + n]
                i += n
        return grads

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
            vals = self.evaluate_points(theta, self.points(req))[0]
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
        if self.exact:
            out[0] += self._exact_points(theta)
        out = [sorted(o, reverse=True) for o in out]
        self._peak_cache = (key, out)
        return out

    def _exact_points(self, theta):
        """The ab13dd peak and the frequencies of the closed-loop modes (where lightly damped resonances
        narrower than the grid spacing peak), as (value, w) pairs of the plain H-inf channel."""
        ch = self.channels[0]
        g, wpk = self.exact_peak(theta)
        if self._exact_stab is None:
            lam = np.linalg.eigvals(_cl_A(self._exact_part, *self.matrices(theta)[0]))
        else:
            lam = self._eigvals(theta)[self._exact_stab]
        wm = np.abs(np.angle(lam)) / ch.dt if ch.dt else np.abs(lam.imag)
        wm = np.unique(np.clip(wm[wm > 0], ch.lo, ch.hi))
        pts = [(float(g), float(min(max(wpk, ch.lo), ch.hi)))]
        if wm.size:
            v = self.evaluate_points(theta, self.points([(0, wm)]))[0][0]
            pts += [(float(a), float(b)) for a, b in zip(v, wm) if a >= 0.3 * g]
        return sorted(pts, reverse=True)

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

    The values and the Jacobian depend on the controller part ``z[:nx]`` only (t enters the rows linearly),
    so both are cached by it. SLSQP's line search asks for the values at trial points (five to ten per
    iteration on the cascade specs, about one on hinfstruct's problems) and for the Jacobian at the accepted
    one, so the values are computed alone (no controller derivatives, eigenvalues without eigenvectors) but
    keep what the Jacobian needs (the LFT and its SVD, the closed-loop A), which completes them on request.
    """

    def __init__(self, prob: _Problem, active, activeP):
        self.prob = prob
        self.nx = int(prob.free.sum())
        self.chans = [ci for ci in range(len(prob.channels)) if len(active[ci])]
        self.pts = prob.points([(ci, active[ci]) for ci in self.chans], [np.array(activeP[ci]) for ci in self.chans])
        self._fkey = self._jkey = None

    def _channels(self, z):
        key = z[:self.nx].tobytes()
        if key != self._fkey:
            th = self.prob.theta(z[:self.nx])
            vals, ctx = self.prob.point_values(th, self.pts)
            self._fkey, self._fval = key, (th, vals, ctx, self.prob.eig_terms(th))
        return self._fval

    def fun(self, z):
        prob, nx = self.prob, self.nx
        _, vals, _, eig = self._channels(z)
        rows = []
        for ci, v in zip(self.chans, vals):
            if prob.is_soft[ci]:
                rows.append(z[nx] - v)            # t - v
            if prob.is_hard[ci]:
                rows.append(HARD_BOUND - v)
        return np.concatenate(rows + [eig - prob.qp_margin])

    def jac(self, z):
        key = z[:self.nx].tobytes()
        if key != self._jkey:
            prob = self.prob
            th, _, ctx, _ = self._channels(z)
            grads = prob.point_grads(th, self.pts, ctx)
            dg_eig = prob.eig_terms(th, grad=True)[1]
            rows = []
            for ci, g in zip(self.chans, grads):
                g = (g * prob.scale[:, None]).T  # (nf, nfree) in scaled variables
                if prob.is_soft[ci]:
                    rows.append(np.hstack([-g, np.ones((g.shape[0], 1))]))
                if prob.is_hard[ci]:
                    rows.append(np.hstack([-g, np.zeros((g.shape[0], 1))]))
            rows.append(np.hstack([dg_eig.T, np.zeros((dg_eig.shape[1], 1))]))
            self._jkey, self._jval = key, np.vstack(rows)
        return self._jval


def _sqp(prob: _Problem, x, m, lo, hi, *, max_iter, tol, deadline, history, sub_iter):
    """Trust-region epigraph SQP steps (the tangent program of Apkarian & Noll over the active peak
    frequencies, solved by SLSQP inside a box trust region).

    The iteration stops on the stationarity measure: the decrease predicted by the tangent program over every
    active frequency, relative to the objective; it is zero exactly when zero lies in the convex hull of the
    active gradients (a Clarke-stationary point of the max function over the active set). Returns (x, merit,
    last predicted relative decrease).
    """
    nch = len(prob.channels)
    active = [[] for _ in range(nch)]
    activeP = [[] for _ in range(nch)]

    def add_peaks(theta):
        held = [ci for ci in range(nch) if active[ci]]
        if held:  # drop active frequencies far below the current level: they never bind
            pts = prob.points([(ci, active[ci]) for ci in held], [np.array(activeP[ci]) for ci in held])
            for ci, vals in zip(held, prob.evaluate_points(theta, pts)[0]):
                keep = vals >= 0.3 * vals.max()
                active[ci] = [w for w, k in zip(active[ci], keep) if k]
                activeP[ci] = [p for p, k in zip(activeP[ci], keep) if k]
        peaks = prob.all_peaks(theta)
        for ci, ch in enumerate(prob.channels):
            found = [w for _, w in peaks[ci]]
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
    viol = [m[0]]
    nx = x.size
    pred = np.inf
    for _ in range(max_iter):
        if deadline is not None and time.perf_counter() > deadline:
            break
        sub = _Subproblem(prob, active, activeP)
        t_start = max(v for (v, _), s in zip(m[2], prob.is_soft) if s) * 1.0001
        z0 = np.r_[x, t_start]
        bnds = [(max(lo[i], x[i] - delta), min(hi[i], x[i] + delta)) for i in range(nx)] + [(0.0, None)]
        res = minimize(lambda z: z[nx], z0, jac=lambda z: np.r_[np.zeros(nx), 1.0], method="SLSQP",
                       bounds=bnds, constraints=[{"type": "ineq", "fun": sub.fun, "jac": sub.jac}],
                       options={"maxiter": sub_iter, "ftol": 1e-9})
        xn = np.clip(res.x[:nx], lo, hi)
        if m[0] <= 1e-9:
            pred = max(m[1] - res.x[nx], 0.0) / max(m[1], 1e-300)
        mn = prob.merit(prob.theta(xn))
        if np.isfinite(mn[1]):
            add_peaks(prob.theta(xn))
        if _better(mn, m):
            hit = np.any(np.abs(xn - x) > 0.9 * delta)
            x, m = xn, mn
            delta = min(3 * delta, 100.0) if hit else delta
        else:
            delta *= 0.3
        history.append(m[1])
        viol.append(m[0])
        if (pred < tol and m[0] <= 1e-9) or delta < 1e-6 * (_rms(x, 1.0) if prob.relative_stop else 1.0):
            break
        if m[0] > 1e-9 and len(viol) > INFEASIBLE_WINDOW and viol[-1] > 0.8 * viol[-1 - INFEASIBLE_WINDOW]:
            # hard goals violated and the linearised constraints no longer reduce the violation (the steps
            # leave the stability region or barely move): hand over to the BFGS phase's exact penalty
            break
    return x, m, pred


# ----------------------------------------------------------------------------------------------------------
# Nonsmooth BFGS (HANSO phase 1) and the hybrid
# ----------------------------------------------------------------------------------------------------------

def _weak_wolfe(fg, x, f, g, d, c1=1e-4, c2=0.5, max_eval=40):
    """Weak Wolfe line search by bracketing and bisection (Lewis & Overton 2013, as in HANSO): for a
    nonsmooth ``f`` the strong Wolfe curvature test can never hold across a kink, the weak one can.

    ``f`` may be inf (an unstable closed loop): such a point only shrinks the bracket. Returns
    ``(t, x_t, f_t, g_t, ok)``; on failure the last point with sufficient decrease (t = 0: none)."""
    gd = float(g @ d)
    if not gd < 0:
        return 0.0, x, f, g, False
    lo, hi, t = 0.0, np.inf, 1.0
    keep = (0.0, x, f, g)
    for _ in range(max_eval):
        xt = x + t * d
        ft, gt = fg(xt)
        if not np.isfinite(ft) or ft > f + c1 * t * gd:
            hi = t
        else:
            keep = (t, xt, ft, gt)
            if gt @ d < c2 * gd:
                lo = t
            else:
                return t, xt, ft, gt, True
        t = 2.0 * lo if hi == np.inf else 0.5 * (lo + hi)
        if hi < np.inf and hi - lo <= 1e-13 * max(1.0, hi):
            break
    return keep + (False,)


def _hull_weights(G):
    """Convex weights ``l`` of the smallest-norm vector ``G l`` of the convex hull of the columns of ``G``
    (nx, k): ``min ||G l||, l >= 0, sum l = 1`` as a non-negative least-squares problem with the simplex
    equality as a heavily weighted extra row (scipy's nnls; k is at most a few dozen). Where nnls stops at its
    iteration limit, scipy's bounded-variable least squares solves the same problem."""
    k = G.shape[1]
    if k == 1:
        return np.ones(1)
    w = 1e3 * max(np.abs(G).max(), 1e-300)
    A, b = np.vstack([G, np.full((1, k), w)]), np.r_[np.zeros(G.shape[0]), w]
    try:
        lam, _ = nnls(A, b)
    except RuntimeError:
        # nnls raises at its iteration limit (3 k), which rounding can reach on nearly parallel gradients (COMPleib
        # HE4 with its measurement in other units, on scipy 1.18.1 with numpy 2.5.2); BVLS returns its best point
        lam = lsq_linear(A, b, bounds=(0.0, np.inf), method="bvls").x
    return lam / max(lam.sum(), 1e-300)


def _min_norm_hull(G):
    """Smallest-norm vector of the convex hull of the columns of ``G``: the HANSO / gradient-sampling
    stationarity measure."""
    return G @ _hull_weights(G)


def relative_slope(G, x, f) -> float:
    """Relative Clarke stationarity: ``||h|| max(||x||, 1) / |f|`` with ``h`` the smallest vector of the convex
    hull of the gradients ``G`` (nx, k) at ``x`` (nearby points or active peaks): the relative decrease of ``f``
    that a step of the iterate's own size would give along the best direction, to first order. It is the same
    number when ``f`` is multiplied by a constant (units of the performance signals) and, with the plant-derived
    variables of :func:`hinfstruct`, when the plant's controls or measurements are rescaled; zero exactly at a
    Clarke-stationary point of the max function. The floor of one scaled unit keeps it meaningful at
    ``x = 0``.

    Examples
    --------
    Two active pieces with gradients (1, 2) and (-1, 2) at x = (0, 1), f = 2: the shortest hull vector is
    (0, 2), so a step of the iterate's size lowers f by 2 * 1 / 2 = 100 % to first order:

    >>> import numpy as np
    >>> relative_slope(np.array([[1.0, -1.0], [2.0, 2.0]]), np.array([0.0, 1.0]), 2.0)
    1.0
    """
    return float(np.linalg.norm(_min_norm_hull(G)) * max(float(np.linalg.norm(x)), 1.0)
                 / max(abs(float(f)), 1e-300))


def _stationary(G, x, f, tol, relative) -> bool:
    """HANSO's stopping test on the gradients ``G`` near ``x``: :func:`relative_slope` below ``tol`` when
    ``relative``, else the absolute ``||h|| <= tol max(1, |f|)`` (the stabilisation phase, whose objective is
    the spectral abscissa near zero, and the cascade, whose goals are normalised)."""
    if relative:
        return relative_slope(G, x, f) <= tol
    return bool(np.linalg.norm(_min_norm_hull(G)) <= tol * max(1.0, abs(f)))


def _inv_bfgs_update(H, s, y, sy):
    """BFGS update of the inverse-Hessian approximation ``H`` for the step ``s`` and gradient change ``y``
    (``sy = s @ y > 0``, checked by the caller with its own curvature guard)."""
    r = 1.0 / sy
    Hy = H @ y
    return H - r * (np.outer(s, Hy) + np.outer(Hy, s)) + (r * r * float(y @ Hy) + r) * np.outer(s, s)


def _rms(x, floor=0.0) -> float:
    """Root-mean-square size of ``x``, at least ``floor``."""
    return max(float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else 0.0, floor)


def _stalled(track, window, f, tol) -> bool:
    """The merit ``f`` fell by no more than ``0.1 tol`` (relative) over the last ``window`` iterations."""
    return len(track) > window and track[-window - 1] - f <= 0.1 * tol * max(abs(f), 1e-300)


def _bfgs(fg, x, f, g, *, max_iter, tol, deadline, history, target=None, relative=False):
    """BFGS on a nonsmooth, locally Lipschitz function with weak Wolfe steps (Lewis & Overton). Stops when
    ``f < target``, when the smallest vector in the convex hull of the gradients at the recent iterates
    within a small radius passes :func:`_stationary` (HANSO's test, relative to ``|x|`` and ``|f|`` when
    ``relative``), when the line search finds no decrease, or when the last ``max(20, 3 n)`` iterations
    together gained less than ``tol / 10``."""
    n = x.size
    H = np.eye(n)
    scaled = False
    near = [(x, g)]
    window = max(20, 3 * n)
    track = [f]
    for _ in range(max_iter):
        if (target is not None and f < target) or (deadline is not None and time.perf_counter() > deadline):
            break
        d = -H @ g
        t, xn, fn, gn, ok = _weak_wolfe(fg, x, f, g, d)
        if t == 0.0:
            if scaled:  # a stale metric: retry once along the steepest descent direction
                H, scaled = np.eye(n), False
                continue
            break
        s, y = xn - x, gn - g
        x, f, g = xn, fn, gn
        history.append(f)
        track.append(f)
        sy = float(s @ y)
        if ok and sy > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
            if not scaled:
                H = (sy / float(y @ y)) * np.eye(n)
                scaled = True
            H = _inv_bfgs_update(H, s, y, sy)
        radius = 1e-4 * max(1.0, np.linalg.norm(x))
        near = [(xi, gi) for xi, gi in near if np.linalg.norm(xi - x) <= radius][-n:] + [(x, g)]
        if _stationary(np.column_stack([gi for _, gi in near]), x, f, tol, relative):
            break
        if _stalled(track, window, f, tol):
            break
    return x, f, g


def _gradient_sampling(fg, x, f, g, *, rng, max_iter, tol, deadline, history, radii=GS_RADII, relative=False):
    """Gradient sampling (Burke, Lewis & Overton 2005; HANSO's second phase) with a BFGS metric and sample
    reuse (Curtis & Que 2013), for the points where BFGS stalls.

    At every iteration the gradients at ``n + 1`` points drawn uniformly in a ball of radius ``eps`` around
    ``x`` (points drawn earlier that are still inside the ball are reused, so only the shortfall is drawn)
    and at ``x`` itself are combined into the smallest vector of their convex hull in the metric of the BFGS
    matrix ``H``; ``-H`` times it is a descent direction for every nearby piece of the max function at once,
    which a single gradient (BFGS) is not at a kink. A backtracking Armijo step follows. The radius shrinks
    through ``radii`` (relative to the rms size of x, at least one scaled unit) when the sampled hull passes
    :func:`_stationary` (approximate Clarke stationarity, HANSO's test), when no step
    decreases f, or when the last ``max(20, 3 n)`` steps together gained less than ``tol / 10``."""
    n = x.size
    H = np.eye(n)
    pool = []  # (point, gradient) already evaluated
    window = max(20, 3 * n)
    it = 0
    for rel in radii:
        track = [f]
        while it < max_iter:
            if deadline is not None and time.perf_counter() > deadline:
                return x, f, g
            eps = rel * max(1.0, float(np.sqrt(np.mean(x * x))))
            pool = [(p, gp) for p, gp in pool if np.linalg.norm(p - x) <= eps][-n:]
            need = n - len(pool)
            if need > 0:
                u = rng.standard_normal((need, n))
                u *= (eps * rng.uniform(size=(need, 1)) ** (1.0 / n)) / np.linalg.norm(u, axis=1)[:, None]
                for p in x + u:
                    fp, gp = fg(p)
                    if np.isfinite(fp):
                        pool.append((p, gp))
            G = np.column_stack([g] + [gp for _, gp in pool])
            if _stationary(G, x, f, tol, relative):
                break
            try:
                L = np.linalg.cholesky(H)
            except np.linalg.LinAlgError:
                H, L = np.eye(n), np.eye(n)
            lam = _hull_weights(L.T @ G)  # smallest hull vector in the H metric
            d = -H @ (G @ lam)
            dec = float(-(G @ lam) @ d)
            t, ok = 1.0, False
            for _ in range(30):
                ft, gt = fg(x + t * d)
                if np.isfinite(ft) and ft < f - 1e-8 * t * dec:
                    ok = True
                    break
                t *= 0.5
            if not ok:
                if np.any(H != np.eye(n)):  # a stale metric: retry with steepest descent before shrinking
                    H = np.eye(n)
                    continue
                break
            s, y = t * d, gt - g
            pool.append((x, g))
            x, f, g = x + s, ft, gt
            history.append(f)
            track.append(f)
            it += 1
            sy = float(s @ y)
            if sy > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
                H = _inv_bfgs_update(H, s, y, sy)
            if _stalled(track, window, f, tol):
                break
    return x, f, g


class _Objective:
    """f(x) = the largest soft channel value (exact ab13dd norm for the plain H-inf channel) plus, when the
    problem has hard goals, the exact penalty ``PENALTY * max(0, largest hard value - HARD_BOUND)``, and its
    gradient at the peak frequencies; inf outside the bounds or where the closed loop is not stable (or
    leaves the pole region)."""

    def __init__(self, prob: _Problem, lo, hi):
        self.prob, self.lo, self.hi = prob, lo, hi
        self.hard = [ci for ci, (h, s) in enumerate(zip(prob.is_hard, prob.is_soft)) if h and not s]
        self.evals = 0

    def __call__(self, x):
        self.evals += 1
        prob = self.prob
        if np.any(x < self.lo) or np.any(x > self.hi):
            return np.inf, None
        th = prob.theta(x)
        if not prob.stable(th):
            return np.inf, None
        if prob.exact:
            f, w = prob.exact_peak(th)
            req = [(0, w)]
        else:
            pk = prob.all_peaks(th)
            f, ci, w = max((pk[ci][0][0], ci, pk[ci][0][1]) for ci in range(len(pk)) if prob.is_soft[ci])
            req = [(ci, w)]
            if self.hard:
                h, hci, hw = max((pk[ci][0][0], ci, pk[ci][0][1]) for ci in self.hard)
                if h > HARD_BOUND:
                    f += PENALTY * (h - HARD_BOUND)
                    req.append((hci, hw))
        req = [(ci, np.array([min(max(w, prob.channels[ci].lo), prob.channels[ci].hi)])) for ci, w in req]
        grads = prob.evaluate_points(th, prob.points(req), grad=True)[1]
        g = grads[0][:, 0] + (PENALTY * grads[1][:, 0] if len(grads) > 1 else 0.0)
        return float(f), g * prob.scale


def _hybrid(prob: _Problem, theta_start, lower, upper, *, max_iter, tol, deadline, sub_iter=HYBRID_SUB_ITER,
            rng=None):
    """Rounds of (1) the tangent program over every active peak frequency (trust-region SQP, stopped on its
    stationarity measure) and (2) nonsmooth BFGS with weak Wolfe steps, until a whole round gains less than
    ``tol`` relative or ``max_iter`` iterations are spent; then, when ``rng`` is given, rounds of (3)
    gradient sampling, (1) and (2) under a budget of ``max_iter`` more iterations, until a whole round gains
    less than ``tol``. Returns (theta, merit, history, last predicted relative decrease). With hard goals
    phases 2 and 3 minimise the exact penalty (:class:`_Objective`) and their end point is kept only when it
    is not worse in the merit (violation first, then the objective)."""
    x = prob.x_of(theta_start)
    lo, hi = prob.x_of(lower), prob.x_of(upper)
    fg = _Objective(prob, lo, hi)
    m = prob.merit(prob.theta(x))
    if not np.isfinite(m[1]):
        raise NotStabilisableError("the start does not stabilise the closed loop")
    history = [m[1]]
    pred = np.inf
    cap = max_iter  # iterations of the current stage: tangent program + BFGS, then as many again with sampling
    sampling = False
    while True:
        m_round = m
        if sampling and len(history) <= cap:
            f, g = fg(x)
            xg, f, g = _gradient_sampling(fg, x, f, g, rng=rng, max_iter=min(GS_ROUND, cap + 1 - len(history)),
                                          tol=tol, deadline=deadline, history=history, relative=prob.relative_stop)
            mg = prob.merit(prob.theta(xg))
            if not _better(m, mg):
                x, m = xg, mg
        if len(history) <= cap:
            x, m, pred = _sqp(prob, x, m, lo, hi, max_iter=min(SQP_ROUND, cap + 1 - len(history)), tol=tol,
                              deadline=deadline, history=history, sub_iter=sub_iter)
        if fg.hard and m[0] <= 1e-9 and pred < tol:
            # feasible and stationary for the tangent program with the hard goals as constraints: BFGS on the
            # exact penalty could then only creep along the constraint boundary (the penalty's kink), so the
            # rounds stop here
            break
        if len(history) <= cap:
            f, g = fg(x)
            xb, f, g = _bfgs(fg, x, f, g, max_iter=min(max(BFGS_ROUND, 10 * x.size), cap + 1 - len(history)),
                             tol=tol, deadline=deadline, history=history, relative=prob.relative_stop)
            mb = prob.merit(prob.theta(xb))
            if not _better(m, mb):
                x, m = xb, mb
        if deadline is not None and time.perf_counter() > deadline:
            break
        if _better(m, m_round, tol) and len(history) <= cap:
            continue
        if rng is None or sampling:
            break
        # the tangent program and BFGS have stalled (or spent their budget): rounds that start with gradient
        # sampling, with a budget of as many iterations again, until a whole round gains less than tol
        sampling, cap = True, len(history) + max_iter
    return prob.theta(x), m, history, pred


# ----------------------------------------------------------------------------------------------------------
# Stabilisation phase and its certificate
# ----------------------------------------------------------------------------------------------------------

@dataclasses.dataclass
class StartFailure:
    """A start that found no stabilising controller: the minimised spectral abscissa (continuous) or spectral
    radius - 1 (discrete), both less the stability margin and pole-region terms, and the closed-loop modes no
    controller of the structure moves (the certificate, empty when none was found)."""

    abscissa: float
    fixed_modes: list
    iterations: int


class _Abscissa:
    """phi(x) = -min(stability terms): the spectral abscissa (continuous) or spectral radius - 1 (discrete),
    plus the stability margin, pole-region terms included; its gradient from the eigenvalue derivatives."""

    def __init__(self, prob, lo, hi):
        self.prob, self.lo, self.hi = prob, lo, hi

    def __call__(self, x):
        if np.any(x < self.lo) or np.any(x > self.hi):
            return np.inf, None
        g, dg = self.prob.eig_terms(self.prob.theta(x), grad=True)
        i = int(np.argmin(g))
        return -float(g[i]), -dg[:, i]


def _fixed_modes(prob: _Problem, theta, rng, tol=1e-6):
    """Unstable closed-loop modes that no controller of this structure moves.

    Two kinds of evidence: the PBH test on the plant (``rank [lam I - A, B2] < n`` or ``rank [lam I - A; C2]
    < n``: a mode u cannot reach or y cannot see is a closed-loop eigenvalue for every LTI controller), and,
    for structural fixed modes, an eigenvalue shared by the closed loops of three random controllers of
    widely different size. Returns a list of (eigenvalue, reason)."""
    out = []
    Km = prob.s.matrices(theta)
    for part, dt in zip(prob._parts, prob._stab_dt):
        A, B2, C2 = part["A"], part["B2"], part["C2"]
        n = A.shape[0]
        unstable = (lambda lam: np.abs(lam) >= 1.0) if dt else (lambda lam: lam.real >= 0.0)
        lam0 = np.linalg.eigvals(A) if n else np.zeros(0)
        for lam in lam0[unstable(lam0)]:
            sc = max(1.0, np.abs(A).max())
            if np.linalg.matrix_rank(np.hstack([lam * np.eye(n) - A, B2]), tol * sc) < n:
                out.append((complex(lam), "not controllable from u (PBH rank test)"))
            elif np.linalg.matrix_rank(np.vstack([lam * np.eye(n) - A, C2]), tol * sc) < n:
                out.append((complex(lam), "not observable from y (PBH rank test)"))
        lam_t = np.linalg.eigvals(_cl_A(part, *Km))
        samples = []
        for mag in (0.1, 3.0, 100.0):  # scaled units: loop gains of every order that matters
            th = np.asarray(theta, float).copy()
            th[prob.free] = mag * rng.standard_normal(prob.free.sum()) * prob.scale
            try:
                samples.append(np.linalg.eigvals(_cl_A(part, *prob.s.matrices(th))))
            except (ValueError, np.linalg.LinAlgError):
                continue
        for lam in lam_t[unstable(lam_t)]:
            if any(abs(lam - l0) < 1e-6 * max(1.0, abs(lam)) for l0, _ in out):
                continue
            if samples and all(np.min(np.abs(s - lam)) < 1e-6 * max(1.0, abs(lam)) for s in samples):
                why = "a closed-loop eigenvalue for every sampled controller of this structure (structural fixed mode)"
                out.append((complex(lam), why))
    return out


def _stabilise(prob: _Problem, theta, lower, upper, rng, max_iter=200, tries=3, redraws=2, drift=30.0):
    """Phase 1: minimise the spectral abscissa (spectral radius - 1 when discrete) by nonsmooth BFGS with weak
    Wolfe steps, without step caps, until the closed loop is stable. After a failed try, restart from a random
    point of the size of the best one found (and of at least one scaled unit). Returns the stabilising theta,
    or a :class:`StartFailure` with the minimised abscissa and the fixed-mode certificate.

    Without caps BFGS may stabilise by growing the gain far beyond the start's size (the abscissa often keeps
    falling slowly along a high-gain direction): a random start of mimo8 of rms 2.8 scaled units ended
    stable at 2600, in a basin whose H-inf minimum was 53x the best, where every other start stabilised within
    4x its size. When the stable point is more than ``drift`` times the start's size (at least one unit),
    ``redraws`` more random points of the start's size are stabilised the same way and the smallest stable
    point is kept, so a start keeps the magnitude it was drawn with where a stabilising controller of that
    magnitude is found. A plant that needs a large gain (benchmarks' gain22) still gets it: every attempt
    then ends large, and the first one is kept whenever the redraws find nothing smaller."""
    lo, hi = prob.x_of(lower), prob.x_of(upper)
    fa = _Abscissa(prob, lo, hi)
    x = prob.x_of(theta)
    f, g = fa(x)
    if f < 0:
        return theta
    found, fail = _stabilise_from(prob, fa, x, f, g, lo, hi, rng, max_iter, tries)
    if found is None:
        return StartFailure(float(fail[0]), _fixed_modes(prob, prob.theta(fail[1]), rng), fail[2])
    size = max(1.0, float(np.sqrt(np.mean(x * x))))
    if np.sqrt(np.mean(found * found)) > drift * size:
        for _ in range(redraws):
            u = rng.standard_normal(x.size)
            xr = np.clip(u * size / np.sqrt(np.mean(u * u)), lo, hi)
            fr, gr = fa(xr)
            if not np.isfinite(fr):
                continue
            xs = xr if fr < 0 else _stabilise_from(prob, fa, xr, fr, gr, lo, hi, rng, max_iter, tries)[0]
            if xs is not None and np.sum(xs * xs) < np.sum(found * found):
                found = xs
    return prob.theta(found)


def _stabilise_from(prob, fa, x, f, g, lo, hi, rng, max_iter, tries):
    """One stabilisation from x (``f, g`` = abscissa and gradient there): ``(stable x, None)``, or ``(None,
    (smallest abscissa, its x, iterations))``."""
    best = (f, x)
    iters = 0
    for k in range(tries):
        hist = []
        x, f, g = _bfgs(fa, x, f, g, max_iter=max_iter, tol=1e-10, deadline=None, history=hist, target=0.0)
        iters += len(hist)
        if f < 0:
            # a little further into the stable region, so the H-inf phase does not start at the boundary
            hist = []
            x2, f2, _ = _bfgs(fa, x, f, g, max_iter=20, tol=1e-10, deadline=None, history=hist,
                              target=f - 0.05 * max(abs(f), 1e-3))
            return (x2 if f2 < f else x), None
        if f < best[0]:
            best = (f, x)
        if k + 1 < tries:
            x = np.clip(best[1] + max(1.0, np.linalg.norm(best[1])) * rng.standard_normal(x.size)
                        / np.sqrt(x.size), lo, hi)
            f, g = fa(x)
    return None, (best[0], best[1], iters)


# ----------------------------------------------------------------------------------------------------------
# Starts
# ----------------------------------------------------------------------------------------------------------

def _perturbed_start(prob: _Problem, theta0, rng, spread, lower, upper):
    """Log-normal multiplicative perturbation of ``theta0`` (the cascade tuner's starts: PID gains keep their
    sign and order of magnitude)."""
    th = theta0.copy()
    f = prob.free
    base = th[f]
    mag = np.where(np.abs(base) > 1e-12, np.abs(base), np.median(np.abs(base[np.abs(base) > 1e-12]))
                   if np.any(np.abs(base) > 1e-12) else 1.0)
    th[f] = base * np.exp(spread * rng.standard_normal(base.size)) * np.where(np.abs(base) > 1e-12, 1.0, 0.0) \
        + np.where(np.abs(base) > 1e-12, 0.0, mag * spread * rng.standard_normal(base.size))
    return np.clip(th, lower, upper)


def _scaled_start(prob: _Problem, theta0, rng, lower, upper):
    """A random controller of random size: a Gaussian direction in the scaled variables with an rms size drawn
    log-uniformly over ``prob.start_decades`` around the size of ``theta0`` (one scaled unit when theta0 is
    smaller); the stabilisation phase then makes it stabilising."""
    th = theta0.copy()
    f = prob.free
    ref = _rms(prob.x_of(theta0), 1.0)
    size = ref * 10.0 ** rng.uniform(*prob.start_decades)
    th[f] = rng.standard_normal(f.sum()) * size * prob.scale
    return np.clip(th, lower, upper)


def _run_start(job):
    prob, theta, lower, upper, max_iter, tol, time_limit_s, sub_iter, sampling, seed = job
    t0, c0 = time.perf_counter(), time.process_time()
    rng = np.random.default_rng(seed)
    th = _stabilise(prob, theta, lower, upper, rng)
    if isinstance(th, StartFailure):
        return th
    deadline = None if time_limit_s is None else t0 + time_limit_s
    th, m, hist, pred = _hybrid(prob, th, lower, upper, max_iter=max_iter, tol=tol, deadline=deadline,
                                sub_iter=sub_iter, rng=rng if sampling else None)
    return th, m, hist, pred, (time.perf_counter() - t0, time.process_time() - c0)


def run_starts(prob: _Problem, theta0, lower, upper, *, starts=1, seed=0, n_jobs=1, executor=None, max_iter=60,
               tol=1e-4, time_limit_s=None, spread=None, sub_iter=HYBRID_SUB_ITER, sampling=True, progress=False):
    """Optimise from ``theta0`` and ``starts - 1`` seeded random starts: multiplicative perturbations of
    theta0 with log-std ``spread`` when given (the cascade), else random controllers of log-uniform size
    (:func:`_scaled_start`). Each start first runs the stabilisation phase.

    The starts run through ``executor`` (a :class:`rotorlab.executor.Executor`), else a local process pool
    of ``n_jobs`` workers, else in this process; the result does not depend on which. Returns one entry per
    start: ``(theta, merit, history, predicted relative decrease, (wall s, CPU s))`` or a :class:`StartFailure`.
    """
    rng = np.random.default_rng(seed)
    if spread is None:
        thetas = [_scaled_start(prob, theta0, rng, lower, upper) for _ in range(max(starts, 1) - 1)]
    else:
        thetas = [_perturbed_start(prob, theta0, rng, spread, lower, upper) for _ in range(max(starts, 1) - 1)]
    thetas = [np.clip(theta0, lower, upper)] + thetas
    seeds = task_seeds(int(rng.integers(1 << 31)), len(thetas))
    jobs = [(prob, th, lower, upper, max_iter, tol, time_limit_s, sub_iter, sampling, s)
            for th, s in zip(thetas, seeds)]
    return map_tasks(_run_start, jobs, executor=executor, n_jobs=n_jobs or 1, desc="starts", progress=progress)


# ----------------------------------------------------------------------------------------------------------
# hinfstruct front end
# ----------------------------------------------------------------------------------------------------------

@dataclasses.dataclass
class HinfstructResult:
    """Outcome of :func:`hinfstruct`.

    ``gamma`` is the closed-loop H-inf norm computed exactly (SLICOT ab13dd via ``rotorlab.lti.hinfnorm``)
    on the returned controller and the caller's plant; ``starts`` holds the verified gamma of every start (inf when
    a start failed), ``hops`` and ``sweep`` those of the later runs, all three on the plant in its own units, whose
    rounded entries (:data:`SNAP_BITS`) put them within about 1e-7 of the same norms on the caller's plant.
    ``slope`` is the relative stationarity of the returned controller (:func:`relative_slope` over the
    gradients of every frequency peak within :data:`SLOPE_BAND` of gamma, in the plant-derived variables):
    the relative decrease of gamma that a step of the gains' own size would give along the best direction, to
    first order; it means the same whatever the units of the plant's signals, and is zero at a
    Clarke-stationary point whose active set is a few isolated peaks. Where the closed loop's gain is flat over a
    band (a full-order optimum is all-pass) no finite set of peaks represents it and ``slope`` stays large at
    the optimum; ``stationarity``, the tangent program's last predicted relative decrease, is the measure there.
    """

    gamma: float
    controller: ct.StateSpace
    params: dict
    history: list
    starts: list
    success: bool
    structure: Structure
    w_peak: float
    stationarity: float = np.nan  # tangent-program predicted relative decrease at the best start's end point
    slope: float = np.nan         # relative Clarke stationarity of the returned controller
    start_times_s: list = dataclasses.field(default_factory=list)  # wall seconds per start
    start_cpu_s: list = dataclasses.field(default_factory=list)    # CPU seconds per start (its own process)
    hops: list = dataclasses.field(default_factory=list)           # verified gamma of every basin-hopping run
    sweep: list = dataclasses.field(default_factory=list)          # verified gamma of every gain-scale sweep start
    total_cpu_s: float = np.nan                                    # CPU seconds of all starts and hops together


def _plant_band(A, dt, npoints=64):
    """Frequencies (rad/s) that span the plant's modes: a log grid from the smallest to the largest nonzero
    eigenvalue magnitude of A (continuous equivalents when discrete, below Nyquist); a decade either side
    of a single mode, 0.01-100 rad/s without states."""
    ev = np.abs(np.linalg.eigvals(A)) if A.shape[0] else np.zeros(0)
    if dt:
        ev = np.abs(np.log(np.maximum(ev, 1e-300))) / dt
    ev = ev[np.isfinite(ev) & (ev > 1e-9 * max(ev.max(initial=0.0), 1e-300))]
    lo, hi = (ev.min(), ev.max()) if ev.size else (1e-2, 1e2)
    if hi < 1.5 * lo:
        lo, hi = lo / 10, hi * 10
    if dt:
        hi = min(hi, 0.9 * np.pi / dt)
        lo = min(lo, hi / 10)
    return np.logspace(np.log10(lo), np.log10(hi), npoints)


def _band_response(P):
    """The plant's frequency response over :func:`_plant_band` (at ``e^{jw dt}`` when discrete), ``(nw, ny, nu)``."""
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    dt = float(P.dt) if lti.is_discrete(P) else 0.0
    w = _plant_band(A, dt)
    if not A.shape[0]:
        return np.broadcast_to(D, (w.size,) + D.shape).astype(complex)
    pts = np.exp(1j * w * dt) if dt else 1j * w
    return C @ np.linalg.solve(pts[:, None, None] * np.eye(A.shape[0]) - A,
                               np.broadcast_to(B, (w.size,) + B.shape)) + D


def _plant_units(P, nmeas, ncon):
    """Sizes of the plant's controls and measurements, from ``P22`` (u -> y) at the frequencies that matter.

    ``log|P22_ji(jw)|`` is averaged over :func:`_plant_band` with weights proportional to the open-loop
    performance gain ``sigma_max(P11(jw))`` (where the disturbances show in the performance outputs: a lightly
    damped structure's resonances, an unstable or slow mode's low frequencies; uniform where ``P11`` is zero),
    and fitted by least squares as ``log gy_j + log gu_i`` over the entries that are not structurally zero. A
    controller gain ``K_ij`` then closes a loop of about ``|K_ij| gy_j gu_i`` where the performance is at stake,
    and ``1 / (gu_i gy_j)`` is its natural unit. ``P11`` does not depend on the units of u and y, and the weights are
    normalised, so they do not depend on a common factor of w or z either. The split between ``gu`` and ``gy`` (a
    controller state's own units) is fixed by the mean of ``log gu`` equal to the mean log column norm of ``B2``. Every
    step is equivariant: rescaling control ``i`` by ``a_i`` and measurement ``j`` by ``c_j`` multiplies ``gu_i`` by
    ``a_i`` and ``gy_j`` by ``c_j``, to round-off. Returns ``(log gu, log gy)``."""
    nz, nw = P.noutputs - nmeas, P.ninputs - ncon
    B2 = np.asarray(P.B, float)[:, nw:]
    Pf = _band_response(P)
    G = Pf[:, nz:, nw:]
    s11 = np.linalg.svd(Pf[:, :nz, :nw], compute_uv=False)[:, 0]
    wt = s11 / s11.sum() if np.isfinite(s11.sum()) and s11.sum() > 0 else np.full(s11.size, 1.0 / s11.size)
    mag = np.abs(G)                                                      # (nf, ny, nu)
    rms = np.sqrt(np.mean(mag**2, axis=0))
    # structurally zero entries (no path u_i -> y_j) hold only round-off; a zero of a real entry on the grid
    # is floored at a tiny fraction of that entry's own size, which scales with it
    keep = rms > 1e-10 * np.sqrt(rms.max(axis=1, keepdims=True) * rms.max(axis=0, keepdims=True))
    logm = np.einsum("f,fji->ji", wt, np.log(np.maximum(mag, np.maximum(1e-12 * rms, 1e-300))))
    j, i = np.nonzero(keep)
    lgu, lgy = np.zeros(ncon), np.zeros(nmeas)
    if j.size:
        M = np.zeros((j.size, ncon + nmeas))
        M[np.arange(j.size), i] = 1.0
        M[np.arange(j.size), ncon + j] = 1.0
        sol = np.linalg.lstsq(M, logm[j, i], rcond=None)[0]
        lgu, lgy = sol[:ncon], sol[ncon:]
        bn = np.linalg.norm(B2, axis=0)
        has = bn > 0
        t = float(np.mean(np.log(bn[has]) - lgu[has])) if has.any() else 0.0
        lgu, lgy = lgu + t, lgy - t
    return lgu, lgy


def _snap(x):
    """``x`` rounded to :data:`SNAP_BITS` significant bits (signs, zeros and infinities kept)."""
    m, e = np.frexp(np.asarray(x, float))
    return np.ldexp(np.round(m * 2.0**SNAP_BITS) / 2.0**SNAP_BITS, e)


class _PlantUnits:
    """The plant in its own units, and the controller's parameters mapped to and from them.

    Control ``i`` is measured in units of ``gu_i`` and measurement ``j`` in units of ``gy_j`` (:func:`_plant_units`):
    the columns of ``B2`` and of ``D`` on the controls divided by ``gu``, the rows of ``C2`` and of ``D`` on the
    measurements by ``gy``, and those entries rounded to :data:`SNAP_BITS` significant bits (``P``). A parameter that
    carries the units of the plant's signals (:meth:`rotorlab.tune.blocks.Structure.io_exponents`) is then measured in
    ``unit = 1 / prod(gu**eu gy**ey)``; the others (time constants, A of state-space blocks) keep their values. The
    same plant written in other units, with its controller mapped back, gives the same ``P`` and the same parameters
    in these units bit for bit (unless an entry lies within round-off of a rounding boundary: below 1e-6 per entry):
    the whole search then runs the same arithmetic. ``sigma`` is the largest singular value of this plant's ``P22``
    over :func:`_plant_band`."""

    def __init__(self, S: Structure, P, nmeas, ncon):
        lgu, lgy = _plant_units(P, nmeas, ncon)
        A, B, C, D = (np.array(M, float) for M in (P.A, P.B, P.C, P.D))
        nz, nw = C.shape[0] - nmeas, B.shape[1] - ncon
        bs, cs = np.r_[np.ones(nw), np.exp(-lgu)], np.r_[np.ones(nz), np.exp(-lgy)]
        B, C, D = B * bs, cs[:, None] * C, cs[:, None] * D * bs
        B[:, nw:], C[nz:] = _snap(B[:, nw:]), _snap(C[nz:])
        D[nz:], D[:, nw:] = _snap(D[nz:]), _snap(D[:, nw:])
        self.P = ct.ss(A, B, C, D, P.dt)
        eu, ey = S.io_exponents()
        self.io = np.any(eu != 0, axis=1) | np.any(ey != 0, axis=1)
        self.unit = np.where(self.io, np.exp(-(eu @ lgu + ey @ lgy)), 1.0)
        # from the rounded plant, not from _plant_units' response of P rescaled: the same numbers in any units
        G = _band_response(self.P)[:, nz:, nw:]
        self.sigma = np.linalg.svd(G, compute_uv=False)[:, 0] if min(G.shape[1:]) else np.ones(G.shape[0])

    def inward(self, theta):
        """Parameters (or bounds) in the plant's own units, those that carry the signals' units snapped."""
        th = np.array(theta, float)
        th[self.io] = _snap(th[self.io] / self.unit[self.io])
        return th

    def outward(self, theta):
        """Parameters in the units of the caller's plant."""
        return np.asarray(theta, float) * self.unit


def _variable_scale(units: _PlantUnits, theta0, free):
    """Scale of each free parameter in the plant's own units (the optimiser's variables are ``theta / scale``) and
    the log10 range of the random starts' rms size in those variables.

    Parameters that carry the units of the plant's signals are already in their natural unit there (scale 1);
    the others (time constants, set-point weights, A of state-space blocks) keep a unit of their own start value,
    at least a tenth of the largest of them and of 1. The random starts' rms size spans the loop gains from where
    the normalised ``P22`` first crosses 1 in the band of the plant's modes (its 90 % quantile; within 0.1..10
    units) up to where it has crossed 1 almost everywhere (10 % quantile), at least three decades and at most 1000
    units: smaller controllers act like none, which the start from the blocks' values (zero by default) already
    covers, and the optimum of a demanding performance channel lies at loop gains well above one."""
    th = np.abs(np.asarray(theta0, float))
    other = free & ~units.io
    ref = max(float(th[other].max()) if other.any() else 0.0, 1.0)
    scale = np.where(units.io, 1.0, np.maximum(th, 0.1 * ref))
    q10, q90 = np.quantile(np.log10(np.maximum(units.sigma, 1e-300)), [0.1, 0.9])
    lo = float(np.clip(-q90, -1.0, 1.0))
    return scale[free], (lo, float(np.clip(-q10, lo + 3.0, START_TOP)))


def _hinf_problem(S: Structure, P, nmeas, ncon, theta0, free):
    """The problem :func:`hinfstruct` solves: one exact H-inf channel on the plant in its own units, in the variables
    of :func:`_variable_scale`, with the structure's parameters ``theta0`` (the caller's units) as its start and
    fixed values. Returns the :class:`_Problem` and the :class:`_PlantUnits` that map parameters back."""
    units = _PlantUnits(S, P, nmeas, ncon)
    th0 = units.inward(theta0)
    scale, decades = _variable_scale(units, th0, free)
    ch = Channel(units.P, nmeas, ncon, name="hinf", exact_peak=True)
    return _Problem(S, [ch], [(units.P, nmeas, ncon)], free, scale, relative_stop=True, start_decades=decades,
                    theta0=th0), units


def _sweep_decades(sigma, force=False):
    """log10 range of the gain-scale sweep's rms sizes in the plant-derived variables, or None: where the loop
    gains at which the normalised ``P22`` (``sigma``: :attr:`_PlantUnits.sigma`) has crossed 1 almost everywhere in
    the band of the plant's modes (the 10 % quantile of :func:`_variable_scale`) lie beyond the random starts'
    largest size (``10**START_TOP`` units), the sweep covers the sizes from :data:`SWEEP_BELOW` decades under that
    cap to :data:`SWEEP_ABOVE` decades over those gains (``force``: also where they do not, from
    :data:`SWEEP_BELOW` decades under them). Like the units, it is the same in any units of the plant's signals."""
    top = -float(np.quantile(np.log10(np.maximum(sigma, 1e-300)), 0.1))
    if not (top > START_TOP or force):
        return None
    return min(top, START_TOP) - SWEEP_BELOW, top + SWEEP_ABOVE


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


def hinfstruct(P, controller, nmeas: int, ncon: int, *, starts: int | None = None, hops: int | None = None, seed=0,
               sweep: bool | None = None, n_jobs: int = 1,
               executor=None, tol: float = 1e-4, time_limit_s: float | None = None, bounds: dict | None = None,
               max_iter: int = 500, progress: bool = False) -> HinfstructResult:
    """Minimise ``||F_l(P, K(theta))||_inf`` over a fixed-structure controller subject to internal stability.

    Each start runs the stabilisation phase (spectral abscissa minimised by nonsmooth BFGS) and then the
    hybrid optimiser (nonsmooth BFGS, tangent-program polishing; see the module docstring); where the plant calls
    for it, a gain-scale sweep (``sweep``) adds starts at high loop gains; then rounds of basin hopping from the
    best end point run the same two phases from random points around it. All of it runs on the plant in its own
    units (module docstring, "Units"), seeded, so the same plant written in other units of its controls and
    measurements takes the same path to the same controller; the runs go through ``executor``. Their cost is
    ``starts`` plus ``hops`` per round (at least two rounds) times that of one start, plus the sweep's screening
    and its :data:`SWEEP_STARTS` starts where it runs.

    Parameters
    ----------
    P : control.StateSpace
        Generalised plant (continuous or discrete), inputs ``[w; u]``, outputs ``[z; y]``.
    controller : "static", Block, list of Blocks or Structure
        ``"static"``: static output feedback ``u = K y`` (ncon x nmeas). Blocks combine block-diagonally;
        their inputs must add up to ``nmeas`` and outputs to ``ncon``.
    nmeas, ncon : int
        Number of measurements y (last outputs of P) and controls u (last inputs of P).
    starts : int, optional
        Number of starts: the blocks' current values plus ``starts - 1`` seeded random controllers whose
        size is drawn log-uniformly over the decades of loop gain that the plant makes plausible (module
        docstring, "Units"), around the start's size when that is larger. Default :data:`DEFAULT_STARTS`.
    hops : int, optional
        Runs per round of basin hopping from the best end point (:func:`_hop`; 0: none). The rounds end when
        two in a row gain less than 0.1 % (at most six rounds). Two runs that agree to round-off (on CPUs whose
        SIMD kernels round differently) can split at one accept/reject decision into local minima a few percent
        apart; hopping takes both on to the lower one. Default :data:`DEFAULT_HOPS`.
    seed : int or numpy.random.Generator seed
    sweep : bool, optional
        Run the gain-scale sweep (:func:`_scale_sweep`) after the starts: at every size on a log grid of loop gains
        above the random starts' largest, seeded directions screened by their exact norm, the best minimised on
        that size's sphere, and :data:`SWEEP_STARTS` more starts from the lowest of those (its best end point
        competes with the starts' before the hops). Default (None): where the plant makes loop gains plausible
        beyond the random starts' largest size (:func:`_sweep_decades`); True: also elsewhere, over the decade
        below and above the plant's largest plausible loop gain; False: never.
    n_jobs : int
        Local worker processes for the starts when no ``executor`` is given (blocks must then pickle: no
        lambdas in Custom blocks).
    executor : rotorlab.executor.Executor, optional
        Runs the starts (``executor.map``); results do not depend on it.
    tol : float
        Stationarity tolerance, relative: the optimiser stops when the tangent program over every active peak
        frequency predicts less than this relative decrease of gamma, or when the relative slope
        (:func:`relative_slope`) of the gradients near the iterate is below it.
    time_limit_s : float, optional
        Wall-clock budget per start (s).
    bounds : dict, optional
        ``{"block.param": (lower, upper)}``; a parameter with lower == upper is fixed.
    max_iter : int
        Iteration budget per start (BFGS iterations plus tangent-program steps).

    Returns
    -------
    HinfstructResult
        With ``slope``, the relative stationarity of the returned controller (the same in any units).

    Raises
    ------
    NotStabilisableError
        Only with a certificate: an unstable closed-loop mode that no controller of the structure moves.
    StabilisationError
        No start found a stabilising controller and no fixed mode explains it: the message gives the smallest
        spectral abscissa reached and what was tried.

    Examples
    --------
    A static output feedback on a plant with one unstable pole: ``z = [x; u]`` from a disturbance ``w``:

    >>> import control as ct
    >>> from rotorlab import tune
    >>> G = ct.ss([[1.0]], [[1.0, 1.0]], [[1.0], [0.0], [1.0]], [[0, 0], [0, 1], [0, 0]])  # [w, u] -> [z1, z2, y]
    >>> res = tune.hinfstruct(G, "static", nmeas=1, ncon=1, seed=0)
    >>> k = res.controller.D.item()
    >>> bool(k < -1), round(res.gamma, 3)          # stabilising (1 + k < 0), and the optimal gamma
    (True, 1.0)

    ``x' = -x + w + u``, ``z = [x; 0.5 u]``, ``y = x``: the optimal static gain is -4 (closed form
    ``-1/(rho^2 a)``) with gamma ``sqrt(5)/5``, in any units of u and y:

    >>> P = ct.ss([[-1.0]], [[1.0, 1.0]], [[1.0], [0.0], [1.0]], [[0, 0], [0, 0.5], [0, 0]])
    >>> r = tune.hinfstruct(P, "static", 1, 1)
    >>> round(r.gamma, 4), round(r.params["K.k[0,0]"], 3), r.slope < 1e-3
    (0.4472, -4.0, True)
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
    prob, units = _hinf_problem(S, P, nmeas, ncon, theta0, free)
    th0, lo_n, hi_n = prob.theta0, units.inward(lower), units.inward(upper)
    starts = DEFAULT_STARTS if starts is None else int(starts)
    hops = DEFAULT_HOPS if hops is None else int(hops)
    results = run_starts(prob, th0, lo_n, hi_n, starts=starts, seed=seed, n_jobs=n_jobs, executor=executor,
                         max_iter=max_iter, tol=tol, time_limit_s=time_limit_s, progress=progress)
    verify = _Verifier(units.P, nmeas, ncon, S)
    verified = [verify(r) for r in results]
    gammas = [v[0] for v in verified]
    if not np.isfinite(min(gammas)):
        _raise_unstabilised([r for r in results if isinstance(r, StartFailure)], len(results))
    best = verified[int(np.argmin(gammas))]
    swept, sweep_cpu_s = [], 0.0
    sweep_range = _sweep_decades(units.sigma, force=bool(sweep)) if sweep is not False else None
    if sweep_range is not None:
        swept, sweep_cpu_s = _scale_sweep(prob, sweep_range, lo_n, hi_n, verify, seed=seed, n_jobs=n_jobs,
                                          executor=executor, max_iter=max_iter, tol=tol, time_limit_s=time_limit_s)
        best = min([best] + swept, key=lambda v: v[0])
    hopped = []
    if hops > 0:
        best, hopped = _hop(prob, best, lo_n, hi_n, verify, hops=hops, seed=seed, n_jobs=n_jobs,
                            executor=executor, max_iter=max_iter, tol=tol, time_limit_s=time_limit_s)
    _, th_n, hist, _, pred, _ = best
    th = np.where(fixed, theta0, np.clip(units.outward(th_n), lower, upper))
    S.set_values(th)
    K = S.ss(th)
    g, wpk = lti.hinfnorm(closed_loop(P, nmeas, ncon, K))
    runs = verified + swept + hopped
    return HinfstructResult(gamma=float(g), controller=K, params=dict(zip(names, map(float, th))),
                            history=list(map(float, hist)), starts=[float(x) for x in gammas], success=True,
                            structure=S, w_peak=float(wpk), stationarity=float(pred), slope=_slope(prob, th_n),
                            start_times_s=[float(v[5][0]) for v in verified],
                            start_cpu_s=[float(v[5][1]) for v in verified],
                            hops=[float(v[0]) for v in hopped], sweep=[float(v[0]) for v in swept],
                            total_cpu_s=float(np.nansum([v[5][1] for v in runs])) + sweep_cpu_s)


class _Verifier:
    """``(gamma, theta, history, peak frequency, predicted decrease, (wall s, CPU s))`` of one run, gamma the exact
    closed-loop norm (inf for a :class:`StartFailure`)."""

    def __init__(self, P, nmeas, ncon, S):
        self.P, self.nmeas, self.ncon, self.S = P, nmeas, ncon, S

    def __call__(self, r):
        if isinstance(r, StartFailure):
            return (np.inf, None, None, None, np.nan, (np.nan, np.nan))
        th, _, hist, pred, secs = r
        g, wpk = lti.hinfnorm(closed_loop(self.P, self.nmeas, self.ncon, self.S.ss(th)))
        return (g, th, hist, wpk, pred, secs)


def _hop(prob: _Problem, best, lower, upper, verify, *, hops, seed, n_jobs, executor, max_iter, tol, time_limit_s):
    """Basin hopping from the best end point: rounds of ``hops`` runs (stabilisation, then the hybrid optimiser)
    from random points around it, at the distances :data:`HOP_SIZES` relative to its rms size in the scaled
    variables; a round's best replaces it when lower by more than ``tol`` relative, and the hopping ends after
    :data:`HOP_PATIENCE` rounds in a row that gain less than :data:`HOP_GAIN` (or :data:`HOP_ROUNDS` rounds).

    Why: two runs that agree to round-off (on another CPU, with another number of BLAS threads) can split at one
    accept/reject decision and end in different local minima a few percent apart; hopping from either end point
    reaches the lower of the nearby minima, so the result no longer hangs on that decision. The perturbations are
    drawn in the plant-derived variables from a seed of their own. Returns the new best and every hop's verified
    entry."""
    rng = np.random.default_rng(task_seeds(seed, 2)[1])
    hopped = []
    idle = 0
    for _ in range(HOP_ROUNDS):
        x = prob.x_of(best[1])
        size = _rms(x, 1.0)
        thetas = []
        for k in range(hops):
            u = rng.standard_normal(x.size)
            thetas.append(np.clip(prob.theta(x + HOP_SIZES[k % len(HOP_SIZES)] * size * u / _rms(u, 1e-300)),
                                  lower, upper))
        seeds = task_seeds(int(rng.integers(1 << 31)), hops)
        jobs = [(prob, th, lower, upper, max_iter, tol, time_limit_s, HYBRID_SUB_ITER, True, s)
                for th, s in zip(thetas, seeds)]
        found = [verify(r) for r in map_tasks(_run_start, jobs, executor=executor, n_jobs=n_jobs or 1)]
        hopped += found
        top = min(found, key=lambda v: v[0])
        idle = 0 if top[0] < best[0] * (1.0 - HOP_GAIN) else idle + 1
        if top[0] < best[0] * (1.0 - tol):
            best = top
        if idle >= HOP_PATIENCE:
            break
    return best, hopped


def _sweep_directions(prob: _Problem, rng, n):
    """``n`` random directions (rows) of rms 1 in the free scaled variables. Every third is Gaussian; in the others
    the free entries of each static-gain block are the rank-one matrix ``u v'`` of two Gaussian vectors (the
    parameters of other blocks Gaussian): the high-gain optima of static output feedback on lightly damped
    structures are nearly rank one (one combination of the measurements drives the controls), and such a
    direction stabilises at high gain where a Gaussian one hardly ever does."""
    T = rng.standard_normal((n, prob.free.size))
    rank_one = np.arange(n) % 3 != 0
    i = 0
    for b in prob.s.blocks:
        k = len(b.params)
        if isinstance(b, StaticGain):
            u, v = rng.standard_normal((n, b.nu)), rng.standard_normal((n, b.ny))
            T[rank_one, i:i + k] = np.einsum("ni,nj->nij", u, v).reshape(n, k)[rank_one]
        i += k
    D = T[:, prob.free]
    return D / np.maximum(np.sqrt(np.mean(D * D, axis=1)), 1e-300)[:, None]


def _sphere_min(fg, d, radius, tol, max_iter=100):
    """Nonsmooth BFGS (:func:`_bfgs`) on the sphere ``|x| = radius`` from the direction ``d``, in the variables
    ``m`` with ``x = radius m / |m|`` (the gradient projected on the sphere's tangent space): the lowest objective at
    that size near ``d``. Returns ``(value, x)``; ``(inf, radius d / |d|)`` where ``d`` does not stabilise."""

    def on_sphere(m):
        nm = np.linalg.norm(m)
        f, g = fg(radius * m / nm)
        if not np.isfinite(f):
            return f, None
        mh = m / nm
        return f, (radius / nm) * (g - mh * (mh @ g))

    m = np.asarray(d, float) / np.linalg.norm(d)
    f, g = on_sphere(m)
    if np.isfinite(f):
        m, f, _ = _bfgs(on_sphere, m, f, g, max_iter=max_iter, tol=tol, deadline=None, history=[], relative=True)
    return f, radius * m / np.linalg.norm(m)


def _sweep_size(job):
    """One size of the gain-scale sweep: the directions ``D`` at rms size ``10**lg`` screened by their exact norm
    (stabilising ones only), the :data:`SWEEP_REFINE` best minimised on that sphere. Returns ``([(value, lg, x),
    ...], CPU s)``."""
    prob, lg, D, lower, upper, tol = job
    c0 = time.process_time()
    lo, hi = prob.x_of(lower), prob.x_of(upper)
    vals = np.full(len(D), np.inf)
    for k, d in enumerate(D):
        x = 10.0 ** lg * d
        if np.any(x < lo) or np.any(x > hi):
            continue
        th = prob.theta(x)
        if prob.stable(th):
            vals[k] = prob.exact_peak(th)[0]
    fg = _Objective(prob, lo, hi)
    radius = 10.0 ** lg * np.sqrt(D.shape[1])
    out = []
    for k in np.argsort(vals, kind="stable")[:SWEEP_REFINE]:
        if np.isfinite(vals[k]):
            f, x = _sphere_min(fg, D[k], radius, tol)
            out.append((f, lg, x))
    return out, time.process_time() - c0


def _sweep_start(job):
    """A start from a sphere minimum of the sweep: its size first optimised (bounded Brent search over log10 size
    within two grid steps, each value the sphere minimum from the same direction: the lowest gamma along the
    scale at that direction's basin), then one run of :func:`_run_start` from the best point found."""
    prob, lg, x, lower, upper, max_iter, tol, time_limit_s, seed = job
    t0, c0 = time.perf_counter(), time.process_time()
    fg = _Objective(prob, prob.x_of(lower), prob.x_of(upper))
    found = {}

    def profile(lgs):
        found[lgs] = _sphere_min(fg, x, 10.0 ** lgs * np.sqrt(x.size), tol)
        return found[lgs][0] if np.isfinite(found[lgs][0]) else 1e300

    minimize_scalar(profile, bounds=(lg - 2 * SWEEP_STEP, lg + 2 * SWEEP_STEP), method="bounded",
                    options={"xatol": 0.1 * SWEEP_STEP})
    f, xs = min(found.values(), key=lambda e: e[0])
    r = _run_start((prob, prob.theta(xs if np.isfinite(f) else x), lower, upper, max_iter, tol, time_limit_s,
                    HYBRID_SUB_ITER, True, seed))
    if isinstance(r, StartFailure):
        return r
    return r[:4] + ((time.perf_counter() - t0, time.process_time() - c0),)


def _scale_sweep(prob: _Problem, decades, lower, upper, verify, *, seed, n_jobs, executor, max_iter, tol,
                 time_limit_s):
    """The gain-scale sweep: starts at the high loop gains that random starts rarely reach.

    Some optima stabilise only in a thin band of gain scale and of direction (a lightly damped structure under
    non-collocated static feedback: flex20s0's best is unstable at half and twice its size), where a random
    start of that size hardly ever stabilises and the optimiser from a smaller one ends in a low-gain valley.
    The sweep looks for them size by size: at every rms size on a log grid over ``decades`` (step
    :data:`SWEEP_STEP`, in the plant-derived variables) :data:`SWEEP_DIRECTIONS` seeded directions
    (:func:`_sweep_directions`, the same set at every size, so each direction is also a ray in scale) are screened by
    their exact norm, and the :data:`SWEEP_REFINE` best stabilising ones are minimised on that size's sphere; the
    :data:`SWEEP_STARTS` lowest sphere minima over all sizes then run :func:`_sweep_start` (their size optimised,
    then the hybrid optimiser). Sizes and starts run through ``executor``. Returns every sweep start's verified
    entry and the CPU seconds of the screening."""
    rng = np.random.default_rng(task_seeds(seed, 3)[2])
    D = _sweep_directions(prob, rng, SWEEP_DIRECTIONS)
    sizes = decades[0] + SWEEP_STEP * np.arange(int(np.floor((decades[1] - decades[0]) / SWEEP_STEP + 1e-9)) + 1)
    jobs = [(prob, float(lg), D, lower, upper, tol) for lg in sizes]
    screened = map_tasks(_sweep_size, jobs, executor=executor, n_jobs=n_jobs or 1, desc="scale sweep")
    cands = sorted((c for found, _ in screened for c in found), key=lambda c: c[0])[:SWEEP_STARTS]
    seeds = task_seeds(int(rng.integers(1 << 31)), SWEEP_STARTS)
    jobs = [(prob, lg, x, lower, upper, max_iter, tol, time_limit_s, s) for (_, lg, x), s in zip(cands, seeds)]
    runs = [verify(r) for r in map_tasks(_sweep_start, jobs, executor=executor, n_jobs=n_jobs or 1,
                                         desc="sweep starts")]
    return runs, float(sum(c for _, c in screened))


def _slope(prob: _Problem, theta) -> float:
    """:func:`relative_slope` at ``theta`` over the gradients of the peaks within :data:`SLOPE_BAND` of the
    largest (the active set of the max function, nearly equal peaks included). Every local peak within 10 %
    is first located to 1e-9 in log frequency (bounded Brent search in its bracket), so which peaks count and
    their gradients (Danskin: the gradient at the peak's frequency) do not depend on grid round-off."""
    ch = prob.channels[0]

    def value(logw):
        return float(prob.evaluate_points(theta, prob.points([(0, np.array([np.exp(logw)]))]))[0][0][0])

    peaks = prob.all_peaks(theta)[0]
    found = []
    for v, wk in peaks:
        if v < 0.9 * peaks[0][0]:
            continue
        lo, hi = np.log(max(wk / 1.02, ch.lo)), np.log(min(wk * 1.02, ch.hi))
        r = minimize_scalar(lambda lw: -value(lw), bounds=(lo, hi), method="bounded", options={"xatol": 1e-9})
        found.append((-r.fun, r.x) if -r.fun > v else (v, np.log(wk)))
    top = max(v for v, _ in found)
    w = np.unique(np.exp([lw for v, lw in found if v >= (1.0 - SLOPE_BAND) * top]))
    G = prob.evaluate_points(theta, prob.points([(0, w)]), grad=True)[1][0] * prob.scale[:, None]
    return relative_slope(G, prob.x_of(theta), top)


def _raise_unstabilised(failures, nstarts):
    best = min(failures, key=lambda f: f.abscissa)
    fixed = {}
    for f in failures:
        for lam, why in f.fixed_modes:
            fixed.setdefault(np.round(lam, 9), why)
    if fixed:
        modes = "; ".join(f"{lam:.6g}: {why}" for lam, why in fixed.items())
        raise NotStabilisableError(
            f"not stabilisable by this controller structure: the closed loop keeps the unstable mode(s) {modes}. "
            f"The minimised spectral abscissa (spectral radius - 1 when discrete) is {best.abscissa:.6g} "
            f"over {nstarts} start(s).")
    raise StabilisationError(
        f"no stabilising controller was found: {nstarts} start(s) minimised the spectral abscissa (spectral "
        f"radius - 1 when discrete) by nonsmooth BFGS with random restarts ({sum(f.iterations for f in failures)} "
        f"iterations in all) down to {best.abscissa:.6g} > 0, and no closed-loop mode is fixed (PBH test and "
        "random controllers of this structure), so this is not a proof that none exists. Try more starts, a "
        "stabilising initial controller (set the block values), or a higher-order controller.")
