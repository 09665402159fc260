"""H-inf model matching (Bergamasco & Lovera 2013; doc 000/001 "H-inf approach"): the physical parameters
of a grey-box structure are chosen so that its frequency response matches a black-box model in the band
where that model is trustworthy,

``theta_hat = argmin_theta || G_W (G_ns - G_s(theta)) ||_inf``,

with ``G_ns`` the black-box model converted to continuous time by ZOH inversion and ``G_W`` a low-pass
weight (published: 15th-order Butterworth, cut-off 7 rad/s). The delay removed before black-box
identification is kept out of the matching and put back into the result for validation.

The papers solve the non-smooth problem with hinfstruct (Apkarian & Noll). Here: a weighted least-squares
fit on a dense log grid gives a smooth start, then the grid maximum is minimised in epigraph form with
SLSQP (``min t  s.t.  |E(jw_i)|^2 <= t``), the grid refined at the exact peak (SLICOT ab13dd through
:func:`rotorlab.lti.hinfnorm`) between rounds; a few seeded restarts guard against local minima.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import control as ct
import numpy as np
import scipy.optimize as opt
import scipy.signal as sig
from tqdm.auto import tqdm

from rotorlab.ident.freqresp import model_frf
from rotorlab.ident.greybox import GreyBoxModel
from rotorlab.lti import as_ss, d2c_zoh, freqresp, hinfnorm, is_discrete

__all__ = ["butterworth_weight", "hinf_match", "HinfMatchResult"]


def butterworth_weight(order: int = 15, cutoff_rad_s: float = 7.0) -> ct.StateSpace:
    """Analog Butterworth low-pass ``G_W`` (default: the published 15th order, 7 rad/s), as a StateSpace.

    Poles from ``scipy.signal.buttap``, realised as a cascade of unit-DC-gain first- and second-order
    sections: a 15th-order companion (polynomial) form is so ill-conditioned that its frequency response
    and H-inf norm come out visibly wrong.

    Parameters
    ----------
    order : int
        Filter order.
    cutoff_rad_s : float
        The -3 dB frequency, rad/s.

    Returns
    -------
    StateSpace
        Unit DC gain, continuous.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> W = ident.butterworth_weight()
    >>> W.nstates, round(float(abs(ct.evalfr(W, 7j))), 4)   # -3 dB at the 7 rad/s cut-off
    (15, 0.7071)
    """
    _, poles, _ = sig.buttap(order)
    poles = poles * cutoff_rad_s
    sections = []
    for p in poles:
        if abs(p.imag) < 1e-12 * cutoff_rad_s:
            sections.append(ct.ss([[p.real]], [[-p.real]], [[1.0]], [[0.0]]))
        elif p.imag > 0:
            wn2, two_zw = abs(p) ** 2, -2.0 * p.real
            sections.append(ct.ss([[0.0, 1.0], [-wn2, -two_zw]], [[0.0], [wn2]], [[1.0, 0.0]], [[0.0]]))
    W = sections[0]
    for sec in sections[1:]:
        W = ct.series(W, sec)
    return W


@dataclass
class HinfMatchResult:
    """Result of :func:`hinf_match`.

    Attributes
    ----------
    params : dict[str, float]
        Every structure parameter at the optimum (the delay parameter set to the black-box delay).
    norm : float
        Achieved ``||G_W (G_ns - G_s)||_inf`` (exact, ab13dd).
    w_peak : float
        Frequency of that peak (rad/s).
    sys : control.StateSpace
        Continuous structured model, delay-free.
    delay_s : float
        Delay reinstated for validation (s).
    model : GreyBoxModel
        The structure with the matched values.
    black_box : control.StateSpace
        The continuous-time black-box model that was matched.
    success : bool
    message : str
    """

    params: dict
    norm: float
    w_peak: float
    sys: ct.StateSpace
    delay_s: float
    model: GreyBoxModel
    black_box: ct.StateSpace
    success: bool
    message: str


def _black_box_ct(black_box, delay_s):
    """Continuous delay-free black box and its delay (s) from an IdentifiedModel / LTI system."""
    if hasattr(black_box, "sys") and hasattr(black_box, "delay"):
        sysd = as_ss(black_box.sys)
        if delay_s is None and is_discrete(sysd):
            delay_s = black_box.delay * float(sysd.dt)
    else:
        sysd = as_ss(black_box)
    # a black box from subspace identification is minimal; one built otherwise may carry cancelled
    # (e.g. integrating) modes that would make the error system's norm infinite
    sysd = _minimal(sysd)
    return (d2c_zoh(sysd) if is_discrete(sysd) else sysd), float(delay_s or 0.0)


def _minimal(sys: ct.StateSpace) -> ct.StateSpace:
    # structures may carry unobservable modes (the pitch structure's common-mode angle at s = 0) that the
    # exact norm of a stable error system must not see
    return ct.minreal(sys, verbose=False)


def hinf_match(black_box, structure: GreyBoxModel, weight=None, theta0: Mapping[str, float] | None = None, *,
               delay_s: float | None = None, omega=None, restarts: int = 3, rng=None,
               progress: bool = False) -> HinfMatchResult:
    """Structured model from a black-box model by weighted H-inf model matching.

    Parameters
    ----------
    black_box : IdentifiedModel, control.StateSpace or TransferFunction
        Unstructured model, delay removed; discrete (converted with :func:`rotorlab.lti.d2c_zoh`) or
        continuous. An ``IdentifiedModel``'s ``delay`` (samples) is reinstated in the result.
    structure : GreyBoxModel
        Continuous structure; its free parameters are matched (bounds respected) and its delay is
        ignored for the matching.
    weight : control system, optional
        ``G_W``; default :func:`butterworth_weight` (15th order, 7 rad/s, as published).
    theta0 : dict, optional
        Initial values overriding the structure's.
    delay_s : float, optional
        Delay to reinstate (s) when ``black_box`` does not carry one.
    omega : array_like, optional
        Frequency grid in rad/s (default 400 log-spaced points from 1e-2 rad/s to 20x the weight's
        bandwidth, capped at the black box's Nyquist frequency).
    restarts : int
        Extra starts, log-uniform within a factor 3 of ``theta0`` (seeded by ``rng``).

    Returns
    -------
    HinfMatchResult

    Examples
    --------
    The published rate form matched to the published P2-A2 test-bed model from a start 20 % off: the match
    recovers the coefficients.

    >>> import control as ct
    >>> from rotorlab import ident
    >>> black_box = ct.tf([12.517, 36.374], [1, 5.583, 21.3])
    >>> start = ident.rate_tf_structure(K=10.0, z=3.5, a=4.5, b=25.0)
    >>> res = ident.hinf_match(black_box, start, delay_s=0.06, restarts=0)
    >>> print(np.round([res.params[k] for k in ("K", "z", "a", "b")], 2))
    [12.52  2.91  5.58 21.3 ]
    """
    Gns, delay = _black_box_ct(black_box, delay_s)
    W = butterworth_weight() if weight is None else as_ss(weight)
    if omega is None:
        bw = ct.bandwidth(ct.ss2tf(W)) if W.nstates else np.inf
        top = 20 * bw if np.isfinite(bw) else 1e3
        if is_discrete(getattr(black_box, "sys", black_box)):
            top = min(top, np.pi / float(getattr(black_box, "sys", black_box).dt))
        omega = np.logspace(-2, np.log10(top), 400)
    omega = np.sort(np.asarray(omega, dtype=float))
    sp = structure.scaled(theta0)
    lo, hi, x_init, scale, theta_of = sp.lo, sp.hi, sp.x_init, sp.scale, sp.theta
    cache = {}

    def fixed_part(w):
        # the weight and the black box do not depend on theta: evaluate them once per grid
        key = (w.size, float(w[0]), float(w[-1]), float(w.sum()))
        if key not in cache:
            cache[key] = (freqresp(W, w)[:, 0, 0], freqresp(Gns, w)[:, 0, 0])
        return cache[key]

    def err(z, w):
        try:
            Gs = structure.ss(theta_of(z))
        except (ValueError, np.linalg.LinAlgError):
            return np.full((w.size,), 1e6, dtype=complex)
        Fw, Fns = fixed_part(w)
        # one batched solve (model_frf), not lti.freqresp's loop over frequencies: the structures have a handful
        # of states and this runs inside the optimiser, where a per-frequency Python loop would dominate
        return Fw * (Fns - model_frf(Gs, w)[:, 0, 0])

    def exact(z):
        E = ct.series(ct.parallel(Gns, -_minimal(structure.ss(theta_of(z)))), W)
        gam, wpk = hinfnorm(E)
        # the exact norm bounds the grid maximum from above; a value below it means a reduction dropped a
        # mode that mattered (extreme parameters), so fall back to the grid
        g = np.abs(err(z, omega))
        k = int(np.argmax(g))
        return (gam, wpk) if gam >= g[k] * (1 - 1e-9) else (float(g[k]), float(omega[k]))

    rng = np.random.default_rng(rng)
    starts = [x_init / scale]
    for _ in range(restarts):
        zz = x_init * np.exp(rng.uniform(-np.log(3.0), np.log(3.0), x_init.size))
        starts.append(np.clip(zz, lo, hi) / scale)
    bounds_z = (lo / scale, hi / scale)

    best = None
    for z0 in tqdm(starts, desc=f"hinf match {structure.name}", disable=not progress):
        ls = opt.least_squares(lambda z: np.concatenate([(e := err(z, omega)).real, e.imag]), z0,
                               bounds=bounds_z, method="trf", x_scale="jac")
        z = ls.x
        gam, wpk = exact(z)
        grid = omega
        msg = "least-squares start"
        for _ in range(3):
            if np.isfinite(wpk) and wpk > 0:
                grid = np.unique(np.concatenate([grid, wpk * np.linspace(0.9, 1.1, 11)]))
            t0 = float(np.max(np.abs(err(z, grid)) ** 2)) * 1.01 + 1e-300
            cons = {"type": "ineq", "fun": lambda x, g=grid: x[-1] - np.abs(err(x[:-1], g)) ** 2}
            bnds = [(a if np.isfinite(a) else None, b if np.isfinite(b) else None)
                    for a, b in zip(*bounds_z)] + [(0.0, None)]
            res = opt.minimize(lambda x, t0=t0: x[-1] / t0, np.append(z, t0), method="SLSQP", constraints=[cons],
                               bounds=bnds, options={"maxiter": 200, "ftol": 1e-12})
            znew = res.x[:-1]
            gnew, wnew = exact(znew)
            if not gnew < gam:
                break
            z, gam, wpk, msg = znew, gnew, wnew, str(res.message)
        if best is None or gam < best[1]:
            best = (z, gam, wpk, msg)
    z, gam, wpk, msg = best
    th = theta_of(z)
    if isinstance(structure.delay, str):
        th[structure.delay] = delay
    model = structure.with_values(th)
    return HinfMatchResult(params=th, norm=float(gam), w_peak=float(wpk), sys=model.ss(), delay_s=delay,
                           model=model, black_box=Gns, success=bool(np.isfinite(gam)), message=msg)
