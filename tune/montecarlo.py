"""Monte Carlo robustness check with random additive uncertainty (ref. 000, "Monte Carlo simulation
results"): ``n`` plants ``G = G_nom + W_delta Delta`` with random stable ``Delta`` of peak gain ``h``
(``h = h_lim`` as published, and above it), each closed by the user's controller, and their set-point and
load-change step responses summarised as bands and statistics. At ``h <= h_lim`` the small-gain theorem
already guarantees stability, so the run only measures performance there; :func:`worst_case_delta` gives the
one ``Delta`` of peak ``h`` that defeats the loop as soon as ``h > h_lim``, which shows the bound is tight.

Reproducibility: sample ``i`` draws from its own ``numpy.random.Generator`` seeded by the ``i``-th child
of ``SeedSequence(seed)``, so the results do not depend on ``n_jobs`` or on the chunking.
"""

from __future__ import annotations

import dataclasses
import math
import os

import control as ct
import numpy as np
import scipy.linalg as sla
import scipy.signal

from rotorlab import lti
from rotorlab.errors import DataError
from rotorlab.executor import Executor, map_tasks
from rotorlab.stepresponse import step_metrics

__all__ = ["MonteCarloResult", "montecarlo", "random_delta", "single_loop", "worst_case_delta",
           "MARGINAL_TOL"]

#: a closed-loop pole within this distance of the stability boundary (spectral abscissa: max Re p, or
#: max |p| - 1 when discrete) is marginal: neither counted stable nor unstable. At h = h_lim a static Delta
#: can put a pole exactly on the boundary (e.g. at z = 1 when the peak is at DC), where rounding decides the sign.
MARGINAL_TOL = 1e-6


def single_loop(G, C) -> ct.StateSpace:
    """Closed loop ``u = C (r - y)``, ``y = G (u + d)`` with inputs ``(r, d)`` and outputs ``(y, u)``.

    Built as a lower LFT so direct feedthrough in both ``G`` and ``C`` (a static ``Delta``) is solved
    exactly; use ``functools.partial(single_loop, C=C)`` as a picklable ``closed_loop_builder``.

    Parameters
    ----------
    G, C : StateSpace
        Plant and controller, SISO, in the same time domain.

    Returns
    -------
    StateSpace
        The closed loop, inputs ``(r, d)``, outputs ``(y, u)``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, C = ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1]))    # plant 1/(s + 1), proportional gain 2

    >>> cl = tune.single_loop(G, C)                              # inputs (r, d), outputs (y, u)
    >>> print(np.round(ct.dcgain(cl), 4))                        # y/r = 2/3, y/d = 1/3, u/r = 2/3, u/d = -2/3
    [[ 0.6667  0.3333]
     [ 0.6667 -0.6667]]
    """
    G, C = lti.as_ss(G), lti.as_ss(C)
    A, B, Cg, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
    n = A.shape[0]
    P = ct.ss(A, np.hstack([np.zeros((n, 1)), B, B]),
              np.vstack([Cg, np.zeros((1, n)), -Cg]),
              np.array([[0.0, D[0, 0], D[0, 0]], [0.0, 0.0, 1.0], [1.0, -D[0, 0], -D[0, 0]]]), G.dt)
    return P.lft(C, nu=1, ny=1)


def random_delta(rng: np.random.Generator, h: float, dt: float = 0.0, w_band=(0.1, 100.0),
                 static_fraction: float = 0.2) -> ct.StateSpace:
    """One random stable SISO uncertainty ``Delta`` with ``||Delta||_inf = h`` exactly.

    With probability ``static_fraction`` a constant ``+-h``; otherwise a first- or second-order system
    whose pole frequency is log-uniform in ``w_band`` (rad/s; second order: damping uniform in
    [0.05, 1]) and whose numerator coefficients are Gaussian (so zeros may lie anywhere, Delta need not be
    minimum phase). Discrete (``dt > 0``): the ZOH image of such a system, the band clipped below
    ``0.8 pi/dt``. Normalised by the exact H-inf norm. Written here rather than with ``control.rss`` /
    ``drss`` because those draw from NumPy's global state and cannot take a seeded Generator.

    Parameters
    ----------
    rng : numpy.random.Generator
        The draw's random stream.
    h : float
        The exact H-inf norm of the result.
    dt : float
        Sample time of a discrete ``Delta``, s (0: continuous).
    w_band : (float, float)
        Range of the pole frequency, rad/s.
    static_fraction : float
        Probability of a static ``+-h``.

    Returns
    -------
    StateSpace
        ``Delta``, stable.

    Examples
    --------
    >>> from rotorlab import tune
    >>> from rotorlab.lti import hinfnorm
    >>> D = tune.random_delta(np.random.default_rng(0), h=0.5)
    >>> round(hinfnorm(D)[0], 6), bool(np.all(np.real(D.poles()) < 0))
    (0.5, True)
    """
    if rng.random() < static_fraction:
        return ct.ss([], [], [], [[h * (1.0 if rng.random() < 0.5 else -1.0)]], dt if dt else 0)
    lo, hi = w_band
    if dt:
        hi = min(hi, 0.8 * math.pi / dt)
    wn = math.exp(rng.uniform(math.log(lo), math.log(hi)))
    if rng.random() < 0.5:
        den = [1.0, wn]
        num = rng.standard_normal(2) * [1.0, wn]
    else:
        zeta = rng.uniform(0.05, 1.0)
        den = [1.0, 2 * zeta * wn, wn * wn]
        num = rng.standard_normal(3) * [1.0, wn, wn * wn]
    # scipy's canonical form and a direct augmented-matrix exponential: python-control's tf2ss and c2d
    # cost ~10x more per call and this runs once per sample
    A, B, C, D = scipy.signal.tf2ss(num, den)
    if dt:
        n = A.shape[0]
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n:] = A, B
        E = sla.expm(M * dt)
        A, B = E[:n, :n], E[:n, n:]
    sys = ct.ss(A, B, C, D, dt if dt else 0)
    g, _ = lti.hinfnorm(sys)
    return ct.ss(A, B, C * (h / g), D * (h / g), dt if dt else 0)


def worst_case_delta(W_delta, V_nom, h: float) -> ct.StateSpace:
    """The destabilising ``Delta`` of peak gain ``h``: a phase-matched all-pass, ``h`` times a first-order
    all-pass (or a static +-1) whose phase at the peak frequency ``w0`` of ``|W_delta V_nom|`` makes the loop
    gain ``V_nom W_delta Delta`` real and positive there.

    With ``G = G_nom + W_delta Delta`` and ``V_nom`` the transfer from a signal added to the plant output to
    the input of ``Delta`` (:func:`rotorlab.tune.robust.control_sensitivity`, sign included; an input delay
    in front of ``G_nom + W_delta Delta`` belongs in ``V_nom`` here, since it turns the phase), the perturbed loop is
    ``1 - V_nom W_delta Delta``; at ``w0`` it reads ``1 - h / h_lim``. Scaling ``Delta`` from 0 to ``h`` moves
    a closed-loop pole across the boundary at ``w0`` when the scale passes ``h_lim``, so ``h`` just above
    ``h_lim`` destabilises the loop: the small-gain bound is tight. The all-pass keeps ``|Delta| = h`` at
    every frequency (it is a legitimate member of the family ``||Delta||_inf <= h``).

    Discrete: ``A(z) = (1 - a z) / (z - a)``, whose phase at ``W = w0 dt`` is ``-W - 2 atan2(a sin W, 1 - a
    cos W)`` and sweeps ``(-pi, 0)`` as ``a`` runs over ``(-1, 1)``: the wanted phase ``phi`` (shifted by
    ``pi`` with a sign flip when needed) is met by ``a = sin(b) / sin(b - W)`` with ``b = (phi + W) / 2``.
    Continuous: ``(a - s) / (a + s)`` with ``a = w0 / tan(-phi / 2)``.

    Parameters
    ----------
    W_delta : StateSpace
        Uncertainty shaping filter (SISO).
    V_nom : StateSpace
        Nominal control sensitivity, with every closed-loop state (:func:`rotorlab.tune.robust.control_sensitivity`).
    h : float
        Peak gain of the returned ``Delta``.

    Returns
    -------
    StateSpace
        ``Delta``, stable, ``||Delta||_inf = h``, in the time domain of ``V_nom``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, C = ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1]))    # plant 1/(s + 1), proportional gain 2

    >>> W = ct.ss(ct.tf([0.5], [1]))
    >>> V = tune.control_sensitivity(G, C)
    >>> h = tune.h_lim(W, V)                                     # 1.0
    >>> D = tune.worst_case_delta(W, V, 1.02 * h)
    >>> cl = tune.single_loop(G + W * D, C)
    >>> bool(np.max(np.real(cl.poles())) > 0), bool(np.max(np.real(tune.single_loop(G + W * tune.worst_case_delta(W, V, 0.98 * h), C).poles())) < 0)
    (True, True)
    """
    W, V = lti.as_ss(W_delta), lti.as_ss(V_nom)
    dt = float(W.dt) if lti.is_discrete(W) else 0.0
    if not (h >= 0 and math.isfinite(h)):
        raise DataError(f"h must be a finite non-negative peak gain; got {h}")
    WV = lti.as_ss(ct.series(W, V))
    _, w0 = lti.hinfnorm(WV)
    if math.isfinite(w0):
        L = complex(lti.freqresp(WV, np.array([max(w0, 0.0)]))[0, 0, 0])
    else:  # a continuous norm reached at infinite frequency: the feedthrough, matched by a static Delta
        L, w0 = complex(np.asarray(WV.D, float)[0, 0]), 0.0
    phi = -np.angle(L)  # Delta's phase that makes V W Delta real positive at w0
    sign = 1.0
    if np.sin(phi) > 0:  # the all-pass reaches phases in (-pi, 0): flip the sign, shift by pi
        sign, phi = -1.0, phi - math.pi
    if abs(np.sin(phi)) < 1e-9 or w0 <= 0 or (dt and w0 * dt >= math.pi * (1 - 1e-9)):
        # peak at DC or Nyquist, or a real loop gain there: a static Delta matches it
        return ct.ss([], [], [], [[h * (1.0 if L.real > 0 else -1.0)]], dt if dt else 0)
    if dt:
        Wr = w0 * dt
        b = (phi + Wr) / 2.0
        a = math.sin(b) / math.sin(b - Wr)
        if not abs(a) < 1:
            raise DataError(f"no stable first-order all-pass matches phase {phi:.4g} rad at {w0:.4g} rad/s")
        ap = ct.tf([-a, 1.0], [1.0, -a], dt)
    else:
        a = w0 / math.tan(-phi / 2.0)
        ap = ct.tf([-1.0, a], [1.0, a])
    return lti.as_ss(ap * (sign * h))


@dataclasses.dataclass
class MonteCarloResult:
    """Responses and statistics of a Monte Carlo run.

    Attributes
    ----------
    t : time grid, s (nt,).
    setpoint, load : outputs ``y`` for a unit set-point step and a unit load (input-disturbance) step,
        shape (n, nt); rows of unstable samples are NaN.
    setpoint_u, load_u : the control signal ``u`` when the builder returns it as second output, else None.
    nominal_setpoint, nominal_load : the same for ``G_nom`` (nt,).
    unstable : bool mask (n,) of samples whose closed loop has a pole beyond the stability boundary by more
        than ``marginal_tol`` (spectral abscissa > ``marginal_tol``).
    marginal : bool mask (n,) of samples with a pole within ``marginal_tol`` of the boundary: neither stable
        nor unstable, reported apart and left out of the bands and statistics.
    abscissa : closed-loop spectral abscissa per sample (max Re p, or max abs(p) - 1 when discrete).
    rise_time_s, settling_time_s, overshoot_pct : set-point statistics per sample of
        :func:`rotorlab.stepresponse.step_metrics` for the unit step (NaN where undefined/unstable).
    load_peak : peak ``|y|`` of the load response per sample.
    """

    t: np.ndarray
    setpoint: np.ndarray
    load: np.ndarray
    setpoint_u: np.ndarray | None
    load_u: np.ndarray | None
    nominal_setpoint: np.ndarray
    nominal_load: np.ndarray
    unstable: np.ndarray
    marginal: np.ndarray
    abscissa: np.ndarray
    rise_time_s: np.ndarray
    settling_time_s: np.ndarray
    overshoot_pct: np.ndarray
    load_peak: np.ndarray

    @property
    def fraction_unstable(self) -> float:
        return float(np.mean(self.unstable))

    @property
    def fraction_marginal(self) -> float:
        return float(np.mean(self.marginal))

    @property
    def stable(self) -> np.ndarray:
        """Bool mask of the samples whose every closed-loop pole is inside the boundary by ``marginal_tol``."""
        return ~(self.unstable | self.marginal)

    def band(self, which: str = "setpoint", quantiles=(0.0, 0.05, 0.5, 0.95, 1.0)) -> np.ndarray:
        """Quantiles over the stable samples of ``which`` ('setpoint', 'load', 'setpoint_u', 'load_u'),
        shape (len(quantiles), nt); quantile 0 and 1 are the min/max envelope."""
        data = getattr(self, which, None)
        if data is None:
            raise DataError(f"no '{which}' responses in this result; valid: setpoint, load, setpoint_u, load_u "
                            "(the last two need a builder with u as second output)")
        ok = data[self.stable]
        if ok.shape[0] == 0:
            raise DataError("every sample is unstable or marginal; no band to compute")
        return np.quantile(ok, quantiles, axis=0)

    def summary(self) -> dict:
        """Median and 5/95 % quantiles of the statistics (stable samples), the unstable and marginal fractions."""
        out = {"fraction_unstable": self.fraction_unstable, "fraction_marginal": self.fraction_marginal}
        for k in ("rise_time_s", "settling_time_s", "overshoot_pct", "load_peak"):
            v = getattr(self, k)
            v = v[np.isfinite(v)]
            out[k] = tuple(np.quantile(v, [0.05, 0.5, 0.95])) if v.size else (math.nan,) * 3
        return out


def _simulate(cl: ct.StateSpace, t: np.ndarray):
    """Unit step on each input, all at once: ZOH discretisation is exact for steps."""
    cl = lti.as_ss(cl)
    if lti.is_discrete(cl):
        A, B = np.asarray(cl.A, float), np.asarray(cl.B, float)
    else:
        h = t[1] - t[0]
        n, m = cl.nstates, cl.ninputs
        M = np.zeros((n + m, n + m))
        M[:n, :n], M[:n, n:] = cl.A, cl.B
        E = sla.expm(M * h)
        A, B = E[:n, :n], E[:n, n:]
    C, D = np.asarray(cl.C, float), np.asarray(cl.D, float)
    X = np.zeros((A.shape[0], B.shape[1]))
    Y = np.empty((t.size, C.shape[0], B.shape[1]))
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(t.size):
            Y[k] = C @ X + D
            X = A @ X + B
    return Y  # (nt, outputs, inputs)


def _one(G_nom, W, builder, h, seedseq, t, opts):
    rng = np.random.default_rng(seedseq)
    dt = float(G_nom.dt) if lti.is_discrete(G_nom) else 0.0
    delta = random_delta(rng, h, dt, **opts)
    G = ct.parallel(G_nom, ct.series(delta, W))
    cl = lti.as_ss(builder(G))
    if cl.ninputs < 2:
        raise DataError(f"closed_loop_builder must return a system with inputs (r, d); got {cl.ninputs} input(s)")
    abscissa = lti.spectral_abscissa(cl)
    Y = _simulate(cl, t)
    return abscissa, Y


def _chunk(task):
    """One task of samples: the job (models pickle through :mod:`rotorlab.lti`) and its seeds."""
    G_nom, W, builder, h, t, opts, seeds = task
    return [_one(G_nom, W, builder, h, s, t, opts) for s in seeds]


def montecarlo(G_nom, W_delta, closed_loop_builder, h: float, n: int = 1000, seed=None, n_jobs: int = 1,
               t_final_s: float = 3.0, n_steps: int = 600, w_band=(0.1, 100.0), static_fraction: float = 0.2,
               progress: bool = True, marginal_tol: float = MARGINAL_TOL, executor: Executor | None = None
               ) -> MonteCarloResult:
    """Monte Carlo of ``n`` uncertain plants ``G_nom + W_delta Delta``, ``||Delta||_inf = h``.

    Parameters
    ----------
    G_nom, W_delta : nominal plant and uncertainty filter (SISO, same time domain).
    closed_loop_builder : callable ``G -> StateSpace`` returning the closed loop around plant ``G`` with
        inputs ``(r, d)`` (set-point, load disturbance at the plant input) and outputs ``(y, [u])``, e.g.
        ``functools.partial(single_loop, C=C)`` (pass ``C`` as a StateSpace: converting a transfer
        function on every sample is slow). Picklable when the samples run in other processes.
    h : peak gain of Delta (e.g. :func:`rotorlab.tune.robust.h_lim`).
    n : number of samples. seed : int or ``numpy.random.SeedSequence`` (one child per sample).
    n_jobs : worker processes of a local pool when no ``executor`` is given (with one: its workers size the
        tasks); ``-1`` = all cores. Results do not depend on it.
    t_final_s, n_steps : simulation horizon; discrete plants use their own sample time (n_steps ignored).
    w_band, static_fraction : passed to :func:`random_delta`.
    progress : show a tqdm bar.
    marginal_tol : a closed-loop spectral abscissa within this of zero marks the sample marginal.
    executor : :class:`rotorlab.executor.Executor`, optional: runs the tasks (e.g. a run's Dask executor:
        :func:`rotorlab.executor.map_tasks`); default: a local pool of ``n_jobs``. Results do not depend on it.

    Returns
    -------
    MonteCarloResult
        Step responses of every sample and of the nominal loop, stability masks and step statistics.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, C = ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1]))    # plant 1/(s + 1), proportional gain 2

    >>> from functools import partial
    >>> W = ct.ss(ct.tf([0.5], [1]))
    >>> h = tune.h_lim(W, tune.control_sensitivity(G, C))          # 1.0
    >>> from rotorlab.tune.montecarlo import montecarlo
    >>> res = montecarlo(G, W, partial(tune.single_loop, C=C), 0.9 * h, n=20, seed=0, progress=False)
    >>> int(res.unstable.sum())                                      # below h_lim no sample is unstable
    0
    """
    if n < 1 or int(n) != n:
        raise DataError(f"n must be a positive whole number of samples; got {n}")
    if not (h >= 0 and math.isfinite(h)):
        raise DataError(f"h must be a finite non-negative peak gain; got {h}")
    G_nom, W = lti.as_ss(G_nom), lti.as_ss(W_delta)
    if lti.is_discrete(G_nom) != lti.is_discrete(W) or (lti.is_discrete(W) and not math.isclose(G_nom.dt, W.dt)):
        raise DataError(f"G_nom (dt={G_nom.dt}) and W_delta (dt={W.dt}) must share the time domain")
    if (G_nom.ninputs, G_nom.noutputs, W.ninputs, W.noutputs) != (1, 1, 1, 1):
        raise DataError("montecarlo handles SISO G_nom and W_delta")
    if lti.is_discrete(G_nom):
        t = np.arange(0.0, t_final_s + 1e-12, float(G_nom.dt))
    else:
        t = np.linspace(0.0, t_final_s, n_steps + 1)
    opts = {"w_band": tuple(w_band), "static_fraction": static_fraction}
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    children = ss.spawn(int(n))

    if executor is not None:
        n_jobs = executor.workers
    elif n_jobs in (-1, None):
        n_jobs = os.cpu_count()
    n_jobs = max(int(n_jobs), 1)
    size = max(1, min(50, int(n) // (4 * n_jobs) or 1))
    tasks = [(G_nom, W, closed_loop_builder, h, t, opts, children[i:i + size]) for i in range(0, int(n), size)]
    parts = map_tasks(_chunk, tasks, executor=executor, n_jobs=n_jobs, desc="montecarlo", progress=progress)
    results = [r for part in parts for r in part]  # in task order, so the sample order is fixed

    nom = _simulate(lti.as_ss(closed_loop_builder(G_nom)), t)
    abscissa = np.array([r[0] for r in results])
    unstable = abscissa > marginal_tol
    marginal = np.abs(abscissa) <= marginal_tol
    Y = np.stack([r[1] for r in results])  # (n, nt, outputs, inputs)
    Y[unstable | marginal] = np.nan
    has_u = Y.shape[2] > 1
    stats = [step_metrics(t, y, 1.0) if np.all(np.isfinite(y)) else None for y in Y[:, :, 0, 0]]
    pick = lambda k: np.array([s[k] if s else math.nan for s in stats])  # noqa: E731
    return MonteCarloResult(
        t=t, setpoint=Y[:, :, 0, 0], load=Y[:, :, 0, 1],
        setpoint_u=Y[:, :, 1, 0] if has_u else None, load_u=Y[:, :, 1, 1] if has_u else None,
        nominal_setpoint=nom[:, 0, 0], nominal_load=nom[:, 0, 1], unstable=unstable, marginal=marginal, abscissa=abscissa,
        rise_time_s=pick("rise_time_s"), settling_time_s=pick("settling_time_s"), overshoot_pct=pick("overshoot_pct"),
        load_peak=np.max(np.abs(Y[:, :, 0, 1]), axis=1),
    )
