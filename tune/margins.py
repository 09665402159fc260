"""Classical and disk stability margins of SISO loops, continuous or discrete.

We grid the frequency response densely and refine every crossing with :func:`scipy.optimize.brentq` on
the exact response, instead of calling ``control.stability_margins``: its default method misses or
mis-assigns crossings on the 10-20 state discrete cascade loops this project tunes (the crossings of a
high-order loop are found from polynomial roots, which lose accuracy), and it reports one margin where a
loop has several crossovers.

Conventions
-----------
* ``L`` is the loop transfer function for *negative* feedback (closed loop ``L / (1 + L)``).
* A transport delay ``delay_s`` can be given separately; it enters the response exactly as
  ``exp(-j w delay_s)`` (no Pade), so analytic delay loops can be checked to machine precision.
* Frequencies in rad/s, also for discrete loops (grid over ``(0, pi/dt]``).
* Gain margin: at every phase crossover (``L`` real and negative) the factor ``-1/L``; the reported
  margin is the one closest to 0 dB (MATLAB's ``margin`` convention). Phase margin: ``180 + angle(L)``
  at every gain crossover, the smallest in modulus. Delay margin: the smallest extra delay (s) that
  brings a gain crossover to -180 deg, i.e. ``min(pm_i mod 360) / w_i``.
* Disk margin (Seiler, Packard & Gahinet, "An introduction to disk margins", IEEE Control Systems
  Magazine 40(5), 2020): with skew ``sigma`` the disk margin is ``alpha = 1 / ||S + (sigma - 1)/2||_inf``.
  The balanced (symmetric) case ``sigma = 0`` gives ``alpha = 1 / ||S - 1/2||_inf = 2 / ||S - T||_inf``;
  the loop tolerates simultaneous gain/phase variations ``f = (1 + (1-sigma)/2 d) / (1 - (1+sigma)/2 d)``
  with ``|d| < alpha``, i.e. gains in ``[(2-alpha)/(2+alpha), (2+alpha)/(2-alpha)]`` and phases within
  ``+-2 atan(alpha/2)`` for ``sigma = 0``. The norm is exact (SLICOT ab13dd, :func:`rotorlab.lti.hinfnorm`)
  when there is no separate ``delay_s``; with one it is the gridded peak refined by bounded scalar search.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np
import scipy.optimize as sopt

from rotorlab import lti
from rotorlab.errors import DataError

__all__ = ["Margins", "margins", "crossover_frequencies", "disk_margin"]

_NGRID = 4000


@dataclasses.dataclass(frozen=True)
class Margins:
    """Stability margins of a SISO loop (see the module docstring for the conventions).

    Attributes
    ----------
    gm_db : gain margin in dB (``inf`` without phase crossover); ``w_pc_rad_s`` its frequency.
    pm_deg : phase margin in deg (``inf`` without gain crossover); ``w_gc_rad_s`` its frequency.
    dm_s : delay margin in seconds (``inf`` without gain crossover; phase lags wrap modulo 360 deg).
    disk_alpha : disk margin ``alpha`` (0 when the closed loop is unstable); ``w_disk_rad_s`` its frequency.
    disk_gm_db : ``(low, high)`` gain variation in dB tolerated by the disk; ``disk_pm_deg`` the phase.
    gm_all, w_pc_all, pm_all_deg, w_gc_all : every crossing, ascending in frequency.
    stable : whether the nominal closed loop is stable.
    """

    gm_db: float
    w_pc_rad_s: float
    pm_deg: float
    w_gc_rad_s: float
    dm_s: float
    disk_alpha: float
    w_disk_rad_s: float
    disk_gm_db: tuple
    disk_pm_deg: float
    gm_all: np.ndarray
    w_pc_all: np.ndarray
    pm_all_deg: np.ndarray
    w_gc_all: np.ndarray
    stable: bool


def _check_siso(L) -> ct.StateSpace:
    if isinstance(L, (ct.StateSpace, ct.TransferFunction)):
        sys = lti.as_ss(L)
    else:
        raise DataError(f"margins need a control.StateSpace or TransferFunction loop; got {type(L).__name__}")
    if sys.ninputs != 1 or sys.noutputs != 1:
        raise DataError(f"margins need a SISO loop; got {sys.noutputs} outputs x {sys.ninputs} inputs")
    mats = [np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D)]
    if not all(np.all(np.isfinite(M)) for M in mats):
        raise DataError("the loop model contains NaN or inf entries")
    return sys


def _response(sys, delay_s):
    """Vectorised evaluator of ``L(jw) e^{-jw delay_s}``.

    The crossing refinement evaluates the response thousands of times; with a well-conditioned modal
    decomposition ``A = V diag(lam) V^-1`` each point costs O(n) instead of a dense solve. Defective or
    ill-conditioned ``A`` (repeated integrators) fall back to :func:`rotorlab.lti.freqresp`.
    """
    A = np.asarray(sys.A, dtype=float)
    d = complex(np.asarray(sys.D, dtype=float)[0, 0])
    discrete = lti.is_discrete(sys)
    dt = float(sys.dt) if discrete else 0.0
    modal = None
    if A.size:
        lam, V = np.linalg.eig(A)
        if np.linalg.cond(V) < 1e6:
            cb = (np.asarray(sys.C, float) @ V)[0] * np.linalg.solve(V, np.asarray(sys.B, float))[:, 0]
            modal = (lam, cb)

    def f(w):
        w = np.atleast_1d(np.asarray(w, dtype=float))
        if modal is not None:
            pts = np.exp(1j * w * dt) if discrete else 1j * w
            r = np.sum(modal[1] / (pts[:, None] - modal[0]), axis=1) + d
        elif A.size:
            r = lti.freqresp(sys, w)[:, 0, 0]
        else:
            r = np.full(w.shape, d)
        if delay_s:
            r = r * np.exp(-1j * w * delay_s)
        return r
    return f


def _default_grid(sys, delay_s: float) -> np.ndarray:
    """Log grid spanning the loop's pole/zero frequencies by three decades either side."""
    A = np.asarray(sys.A, dtype=float)
    roots = np.linalg.eigvals(A) if A.size else np.array([])
    try:
        zeros = ct.zeros(sys) if A.size else np.array([])
    except Exception:  # zero computation can fail on degenerate descriptor data; poles suffice then
        zeros = np.array([])
    roots = np.concatenate([roots, zeros])
    if lti.is_discrete(sys):
        dt = float(sys.dt)
        roots = roots[np.abs(roots) > 1e-12]
        mags = np.abs(np.log(roots.astype(complex))) / dt
        w_max = math.pi / dt
    else:
        mags = np.abs(roots)
        w_max = None
    mags = mags[(mags > 1e-9) & np.isfinite(mags)]
    if delay_s:
        mags = np.append(mags, 1.0 / delay_s)
    lo = (mags.min() if mags.size else 1.0) * 1e-3
    hi = (mags.max() if mags.size else 1.0) * 1e3
    if w_max is not None:
        hi = w_max
        lo = min(lo, w_max * 1e-5)
    return np.geomspace(lo, hi, _NGRID)


def _grid(sys, w, delay_s):
    if w is None:
        return _default_grid(sys, delay_s)
    w = np.sort(np.asarray(w, dtype=float).ravel())
    if w.size < 2 or not np.all(np.isfinite(w)) or w[0] <= 0:
        raise DataError(f"frequency grid must hold at least 2 finite positive values (rad/s); got {w.size} values")
    if lti.is_discrete(sys) and w[-1] > math.pi / float(sys.dt) * (1 + 1e-9):
        raise DataError(f"grid exceeds the Nyquist frequency {math.pi / float(sys.dt):.4g} rad/s of the discrete loop")
    return w


def _roots_of(fun, w, vals):
    """Refined roots of a real function sampled as ``vals`` on ``w`` (sign changes, brentq in log w)."""
    out = []
    s = np.sign(vals)
    idx = np.nonzero(s[:-1] * s[1:] < 0)[0]
    for k in idx:
        g = lambda lw: fun(math.exp(lw))  # noqa: E731 - brentq in log-frequency is better conditioned
        out.append(math.exp(sopt.brentq(g, math.log(w[k]), math.log(w[k + 1]), xtol=1e-14, rtol=1e-13)))
    out.extend(w[np.nonzero(vals == 0)[0]])
    return np.sort(np.asarray(out, dtype=float))


def crossover_frequencies(L, w=None, delay_s: float = 0.0) -> np.ndarray:
    """All gain-crossover frequencies (rad/s) of the SISO loop ``L`` (where ``|L| = 1``), ascending.

    Parameters
    ----------
    L : control.StateSpace or TransferFunction, continuous or discrete.
    w : optional grid (rad/s) to search on; default spans the poles/zeros (discrete: up to pi/dt).
    delay_s : extra transport delay in s (does not change ``|L|``; accepted for symmetry with :func:`margins`).

    Returns
    -------
    ndarray
        Crossover frequencies, rad/s, ascending (empty when ``|L|`` never crosses 1).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> print(np.round(tune.crossover_frequencies(ct.tf([10.0], [1, 1, 0])), 3))   # |10/(jw (jw + 1))| = 1
    [3.084]
    """
    sys = _check_siso(L)
    grid = _grid(sys, w, delay_s)
    f = _response(sys, delay_s)
    mag = np.log(np.abs(f(grid)))
    return _roots_of(lambda x: float(np.log(np.abs(f(x)[0]))), grid, mag)


def disk_margin(L, sigma: float = 0.0, delay_s: float = 0.0, w=None) -> tuple[float, float]:
    """Disk margin ``alpha = 1/||S + (sigma-1)/2||_inf`` and its peak frequency (rad/s).

    Returns ``(0.0, nan)`` when the closed loop ``1/(1+L)`` is unstable.

    Parameters
    ----------
    L : StateSpace or TransferFunction
        SISO loop transfer, continuous or discrete, negative feedback.
    sigma : float
        Skew of the disk (0: the balanced disk).
    delay_s : float
        Extra transport delay, s, applied exactly on the frequency response.
    w : array_like, optional
        Frequency grid, rad/s (default: spans the loop's poles and zeros).

    Returns
    -------
    alpha : float
        The disk margin (0 when the closed loop is unstable).
    w_peak_rad_s : float
        The frequency where it is attained, rad/s (nan when unstable).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> alpha, w = tune.disk_margin(ct.tf([2.0], [1, 1]))         # L = 2/(s + 1)
    >>> alpha, w                                                     # S - 1/2 = (s - 1)/(2 (s + 3)) peaks at infinity
    (2.0, inf)
    """
    sys = _check_siso(L)
    if delay_s:
        return _disk_margin_gridded(sys, sigma, delay_s, w)
    S = lti.as_ss(ct.feedback(ct.ss([], [], [], [[1.0]], sys.dt), sys))
    if not lti.is_stable(S):
        return 0.0, float("nan")
    M = S + ct.ss([], [], [], [[(sigma - 1.0) / 2.0]], sys.dt)
    g, wpk = lti.hinfnorm(M)
    return (1.0 / g if g > 0 else float("inf")), wpk


def _disk_margin_gridded(sys, sigma, delay_s, w):
    # A true transport delay has no finite state space, so closed-loop stability is judged on a 9th order
    # Pade approximation and the peak is gridded and refined on the exact delayed response.
    Lp = lti.with_io_delay(sys, delay_s, pade_order=9) if not lti.is_discrete(sys) else lti.with_io_delay(sys, delay_s)
    if not lti.is_stable(ct.feedback(Lp, 1)):
        return 0.0, float("nan")
    grid = _grid(sys, w, delay_s)
    f = _response(sys, delay_s)
    m = lambda x: -abs(1.0 / (1.0 + f(x)[0]) + (sigma - 1.0) / 2.0)  # noqa: E731
    vals = np.abs(1.0 / (1.0 + f(grid)) + (sigma - 1.0) / 2.0)
    k = int(np.argmax(vals))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    res = sopt.minimize_scalar(m, bounds=(lo, hi), method="bounded", options={"xatol": 1e-10 * hi})
    peak = max(vals[k], -res.fun)
    wpk = res.x if -res.fun >= vals[k] else grid[k]
    return 1.0 / peak, float(wpk)


def _disk_to_gain_phase(alpha: float, sigma: float):
    """Gain interval (dB) and phase (deg) of the disk ``D(alpha, sigma)`` (Seiler et al. 2020, sec. 'Disk margins')."""
    a1, a2 = (1.0 - sigma) / 2.0 * alpha, (1.0 + sigma) / 2.0 * alpha
    gmin = (1.0 - a1) / (1.0 + a2)
    gmax = (1.0 + a1) / (1.0 - a2) if a2 < 1.0 else math.inf
    lo = 20 * math.log10(gmin) if gmin > 0 else -math.inf
    hi = 20 * math.log10(gmax) if math.isfinite(gmax) else math.inf
    if not math.isfinite(gmax) or gmin <= 0:
        pm = 90.0 if gmin >= 0 else 180.0
    else:
        # the disk's centre and radius on the real axis; the largest phase is along the tangent from 0
        c, r = (gmin + gmax) / 2.0, (gmax - gmin) / 2.0
        pm = math.degrees(math.asin(min(r / c, 1.0)))
    return (lo, hi), pm


def margins(L, w=None, delay_s: float = 0.0, sigma: float = 0.0) -> Margins:
    """Gain, phase, delay and disk margins of the SISO negative-feedback loop ``L``.

    Parameters
    ----------
    L : control.StateSpace or TransferFunction, continuous (``dt = 0``) or discrete (``dt > 0``).
    w : optional frequency grid in rad/s; default: 4000 log-spaced points spanning the loop's poles and
        zeros by three decades, up to ``pi/dt`` for discrete loops. Crossings are refined by brentq.
    delay_s : extra transport delay in seconds applied exactly on the frequency response.
    sigma : skew of the disk margin (0 = balanced/symmetric disk).

    Returns
    -------
    Margins

    Examples
    --------
    A PI rate loop with the published P2-A2 inner ``kp`` and ``ki`` on the test-bed model (50 Hz, 3-sample delay):

    >>> import control as ct
    >>> from rotorlab.tune.margins import margins
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02) * ct.tf([1], [1, 0, 0, 0], 0.02)
    >>> C = ct.tf([0.257 + 0.643 * 0.02, -0.257], [1, -1], 0.02)      # kp + ki dt/(z - 1)
    >>> m = margins(C * G)
    >>> round(m.gm_db, 1), round(m.pm_deg, 1), m.stable
    (16.5, 118.7, True)
    """
    sys = _check_siso(L)
    if delay_s < 0 or not math.isfinite(delay_s):
        raise DataError(f"delay_s must be a finite non-negative time in s; got {delay_s}")
    grid = _grid(sys, w, delay_s)
    f = _response(sys, delay_s)
    resp = f(grid)

    # gain crossovers
    wgc = _roots_of(lambda x: float(np.log(np.abs(f(x)[0]))), grid, np.log(np.abs(resp)))
    pm_all = np.array([(math.degrees(np.angle(f(x)[0])) + 180.0 + 180.0) % 360.0 - 180.0 for x in wgc])

    # phase crossovers: Im L changes sign where Re L < 0
    wim = _roots_of(lambda x: float(f(x)[0].imag), grid, resp.imag)
    if lti.is_discrete(sys) and math.isclose(grid[-1], math.pi / float(sys.dt)) and resp[-1].real < 0:
        wim = np.append(wim, grid[-1])  # L is real at Nyquist: a crossing exactly at the grid end
    re = np.array([f(x)[0].real for x in wim])
    wpc = wim[re < 0]
    gm_all = -1.0 / re[re < 0]

    if gm_all.size:
        k = int(np.argmin(np.abs(np.log(gm_all))))
        gm_db, w_pc = 20 * math.log10(gm_all[k]), float(wpc[k])
    else:
        gm_db, w_pc = math.inf, math.nan
    if pm_all.size:
        k = int(np.argmin(np.abs(pm_all)))
        pm, w_gc = float(pm_all[k]), float(wgc[k])
        dm = float(np.min(np.mod(np.radians(pm_all), 2 * math.pi) / wgc))
    else:
        pm, w_gc, dm = math.inf, math.nan, math.inf

    alpha, wdm = disk_margin(sys, sigma=sigma, delay_s=delay_s, w=w)
    dgm, dpm = _disk_to_gain_phase(alpha, sigma)
    return Margins(gm_db=gm_db, w_pc_rad_s=w_pc, pm_deg=pm, w_gc_rad_s=w_gc, dm_s=dm, disk_alpha=alpha,
                   w_disk_rad_s=wdm, disk_gm_db=dgm, disk_pm_deg=dpm, gm_all=gm_all, w_pc_all=wpc,
                   pm_all_deg=pm_all, w_gc_all=wgc, stable=alpha > 0)
