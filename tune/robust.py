"""Additive-uncertainty robustness: bootstrap envelope ``W_delta``, control sensitivity and the
robust-stability limit ``h_lim`` (Riccardi, Panizza & Lovera, ref. 000, "Robust stability analysis").

The uncertain family is ``G = G_nom + W_delta Delta`` with ``||Delta||_inf < h``. By the small-gain theorem
the loop stays stable for every stable ``Delta`` with ``||Delta||_inf < h_lim = 1/||W_delta V_nom||_inf``,
where ``V_nom`` is the nominal control sensitivity: the transfer from a signal added to the plant output
(the output of ``W_delta Delta``) to the plant input ``u`` (the input of ``Delta``), with all loops closed.

For a single loop ``u = C (r - y)`` this is ``V = -C/(1 + G C)`` (:func:`control_sensitivity`; the sign
does not change the norm). For a cascade (outer PD on the angle, inner PID on the rate, as in ref. 000),
``G`` is the rate plant ``q/u``; the uncertainty adds to ``q`` and therefore also to the angle (its
integral). Build ``V`` as the closed-loop transfer from that additive signal to ``u`` (e.g. with
``control.interconnect``, naming the summing junction after the rate plant) and pass it as a StateSpace
with all closed-loop states, so that :func:`h_lim` can check internal stability.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np
import scipy.optimize as sopt

from rotorlab import lti
from rotorlab.errors import DataError

__all__ = ["fit_wdelta", "additive_spread", "control_sensitivity", "h_lim", "h_lim_analysis", "HLim"]


def _finite_ss(sys, what: str) -> ct.StateSpace:
    if not isinstance(sys, (ct.StateSpace, ct.TransferFunction)):
        raise DataError(f"{what} must be a control.StateSpace or TransferFunction; got {type(sys).__name__}")
    ss = lti.as_ss(sys)
    for M in (ss.A, ss.B, ss.C, ss.D):
        if not np.all(np.isfinite(np.asarray(M, dtype=float))):
            raise DataError(f"{what} contains NaN or inf entries")
    return ss


def _same_domain(a, b, what: str) -> None:
    da, db = lti.is_discrete(a), lti.is_discrete(b)
    if da != db or (da and not math.isclose(float(a.dt), float(b.dt))):
        raise DataError(f"{what}: models must share the time domain; got dt={a.dt} and dt={b.dt}")


def additive_spread(G_nom, G_reps, w) -> np.ndarray:
    """``max_i sigma_max(G_i(jw) - G_nom(jw))`` over the replicas, on the grid ``w`` (rad/s).

    ``G_reps`` is a sequence of LTI models (same shape and time domain as ``G_nom``). Discrete models are
    evaluated at ``exp(j w dt)``.

    Parameters
    ----------
    G_nom : StateSpace or TransferFunction
        Nominal model.
    G_reps : sequence of StateSpace or TransferFunction
        Replica models.
    w : array_like
        Frequencies, rad/s.

    Returns
    -------
    ndarray
        The largest singular value of the difference at each frequency, over the replicas.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G = ct.tf([1.0], [1, 1])
    >>> print(np.round(tune.additive_spread(G, [0.9 * G, 1.2 * G], [0.0, 1.0]), 4))   # 0.2 |G(jw)|
    [0.2    0.1414]
    """
    G_nom = _finite_ss(G_nom, "G_nom")
    w = np.asarray(w, dtype=float).ravel()
    if len(G_reps) == 0:
        raise DataError("G_reps is empty; fit_wdelta needs at least one bootstrap replica")
    Hn = lti.freqresp(G_nom, w)
    spread = np.zeros(w.size)
    for i, Gi in enumerate(G_reps):
        Gi = _finite_ss(Gi, f"G_reps[{i}]")
        _same_domain(G_nom, Gi, f"G_reps[{i}]")
        if (Gi.noutputs, Gi.ninputs) != (G_nom.noutputs, G_nom.ninputs):
            raise DataError(f"G_reps[{i}] is {Gi.noutputs}x{Gi.ninputs}; expected the shape of G_nom "
                            f"{G_nom.noutputs}x{G_nom.ninputs}")
        dH = lti.freqresp(Gi, w) - Hn
        spread = np.maximum(spread, np.linalg.norm(dH, ord=2, axis=(1, 2)))
    return spread


def _sections(theta, order):
    """Roots (rad/s, open LHP) from the unconstrained parameters: one real root when ``order`` is odd,
    then ``order // 2`` second-order sections ``s^2 + 2 zeta wn s + wn^2`` with ``wn = e^a``, ``zeta = e^b``
    (zeta > 1 covers two real roots), so every candidate is stable and minimum phase by construction."""
    roots = []
    i = 0
    if order % 2:
        roots.append(-math.exp(theta[0]))
        i = 1
    for _ in range(order // 2):
        wn, zeta = math.exp(theta[i]), math.exp(theta[i + 1])
        disc = np.sqrt(complex(zeta * zeta - 1.0))
        roots.extend([wn * (-zeta + disc), wn * (-zeta - disc)])
        i += 2
    return np.array(roots, dtype=complex)


def _params_to_zpk(theta, order):
    np_ = order  # parameters per polynomial: 1 (odd real root) + 2 per section
    zeros = _sections(theta[1:1 + np_], order)
    poles = _sections(theta[1 + np_:1 + 2 * np_], order)
    return zeros, poles, math.exp(theta[0])


def _log_mag(zeros, poles, gain, w, dt):
    if dt:
        # matched pole-zero map: stable/min-phase roots in s map inside the unit circle
        pts = np.exp(1j * w * dt)
        zr, pr = np.exp(zeros * dt), np.exp(poles * dt)
        num = np.sum(np.log(np.abs(pts[:, None] - zr[None, :])), axis=1)
        den = np.sum(np.log(np.abs(pts[:, None] - pr[None, :])), axis=1)
    else:
        s = 1j * w
        num = np.sum(np.log(np.abs(s[:, None] - zeros[None, :])), axis=1)
        den = np.sum(np.log(np.abs(s[:, None] - poles[None, :])), axis=1)
    return math.log(gain) + num - den


def _zpk_to_ss(zeros, poles, gain, dt):
    if dt:
        zr, pr = np.exp(zeros * dt), np.exp(poles * dt)
    else:
        zr, pr = zeros, poles
    num = np.real(np.poly(zr)) * gain
    den = np.real(np.poly(pr))
    return lti.as_ss(ct.tf(num, den, dt if dt else 0))


def fit_wdelta(G_nom, G_reps, w, order: int = 3, under_weight: float = 10.0) -> ct.StateSpace:
    """Stable, minimum-phase shaping filter ``W_delta`` of ``order`` whose magnitude bounds the bootstrap
    spread ``max_i |G_i(jw) - G_nom(jw)|`` at every grid frequency (ref. 000 uses order 3).

    Method: least squares on ``log|W| - log(spread)`` (residuals where ``W`` is below the data weighted by
    ``under_weight``) with :func:`scipy.optimize.least_squares`, over a parametrisation that is stable and
    minimum phase by construction (one real root plus second-order sections, each from log-parameters);
    the gain raised by the worst remaining shortfall; then refined to the least conservative envelope (least
    mean ``log|W| - log(spread)`` subject to ``|W| >= spread`` at every grid point, SLSQP), so ``|W| >=
    spread`` on the whole grid and as close to it as the order allows.

    Parameters
    ----------
    G_nom : nominal LTI model (continuous, or discrete with dt in s).
    G_reps : sequence of replica models (same shape and dt as ``G_nom``), e.g. bootstrap re-estimates.
    w : frequency grid in rad/s, at least ``order + 1`` points (discrete: up to the Nyquist frequency pi/dt
        included: ``h_lim`` takes the norm over the whole band, so the envelope must bound it there too).
    order : filter order (numerator and denominator degree).

    Returns
    -------
    control.StateSpace
        ``W_delta`` with the time domain of ``G_nom``: continuous for continuous models; for discrete
        models a discrete filter whose poles/zeros are the matched (``z = e^{s dt}``) images of the fitted
        continuous roots, fitted and checked directly on ``exp(j w dt)``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G = ct.tf([12.517, 36.374], [1, 5.583, 21.3])
    >>> reps = [ct.tf([12.517 * k, 36.374 * k], [1, 5.583, 21.3]) for k in (0.95, 1.05, 1.1)]  # 10 % gain spread
    >>> w = np.logspace(-1, 2, 200)
    >>> W = tune.fit_wdelta(G, reps, w, order=2)
    >>> bool(np.all(np.abs(ct.frequency_response(W, w).complex.ravel()) >= tune.additive_spread(G, reps, w) * (1 - 1e-9)))
    True
    """
    if int(order) != order or order < 1:
        raise DataError(f"order must be a positive whole number; got {order}")
    order = int(order)
    w = np.asarray(w, dtype=float).ravel()
    if w.size < order + 1:
        raise DataError(f"fit_wdelta needs at least order+1 = {order + 1} frequency points; got {w.size}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise DataError("frequency grid w must be finite and positive (rad/s)")
    G_nom = _finite_ss(G_nom, "G_nom")
    dt = float(G_nom.dt) if lti.is_discrete(G_nom) else 0.0
    if dt and w.max() > math.pi / dt * (1 + 1e-12):
        raise DataError(f"grid reaches {w.max():.4g} rad/s, above the Nyquist frequency {math.pi / dt:.4g} rad/s")
    spread = additive_spread(G_nom, G_reps, w)
    if np.any(spread <= 0):
        raise DataError("the replicas coincide with G_nom at some grid frequency (zero spread); "
                        "the envelope needs a strictly positive spread; drop those frequencies")
    target = np.log(spread)

    def resid(theta):
        e = _log_mag(*_params_to_zpk(theta, order), w, dt) - target
        return np.where(e < 0, under_weight * e, e)

    lw = np.log(w)
    best = None
    # a few deterministic starts with roots spread over the grid: the cost has local minima
    for frac_z, frac_p in ((0.3, 0.7), (0.7, 0.3), (0.5, 0.5)):
        th = [float(np.median(target))]
        for frac in (frac_z, frac_p):
            if order % 2:
                th.append(lw.min() + frac * (lw.max() - lw.min()))
            for k in range(order // 2):
                th += [lw.min() + (frac + 0.1 * (k + 1)) % 1.0 * (lw.max() - lw.min()), math.log(0.7)]
        sol = sopt.least_squares(resid, np.array(th), method="trf", max_nfev=400, ftol=1e-6, xtol=1e-6)
        if best is None or sol.cost < best.cost:
            best = sol
    theta = best.x.copy()
    theta[0] += max(float(np.max(target - _log_mag(*_params_to_zpk(theta, order), w, dt))), 0.0)

    # Raising the gain by the worst shortfall leaves the least-squares fit above the spread by that factor
    # almost everywhere (about 20 % on bootstrap spreads, which is 20 % off h_lim). Refine: the least
    # conservative bound, minimum mean log-excess subject to |W| >= spread at every grid point (SLSQP from
    # the feasible raised fit; kept when it is better once made an upper bound).
    def excess(th):
        return _log_mag(*_params_to_zpk(th, order), w, dt) - target

    # roots within 5 nepers (x150) of the grid, damping ratios within e^+-5: keeps the search finite
    odd = order % 2
    per_poly = [(math.log(w.min()) - 5.0, math.log(w.max()) + 5.0) if k < odd or (k - odd) % 2 == 0 else (-5.0, 5.0)
                for k in range(order)]
    bounds = [(theta[0] - 20.0, theta[0] + 20.0)] + per_poly * 2
    lo, hi = np.array(bounds).T
    try:
        ref = sopt.minimize(lambda th: float(np.mean(excess(th))), np.clip(theta, lo, hi), method="SLSQP",
                            bounds=bounds, constraints=[{"type": "ineq", "fun": excess}],
                            options={"maxiter": 300, "ftol": 1e-10})
        def after_raise(th):  # mean log-excess once the final gain raise has made it an upper bound
            e = excess(th)
            return float(np.mean(e) + max(-e.min(), 0.0))

        if np.all(np.isfinite(ref.x)) and after_raise(ref.x) < after_raise(theta):
            theta = ref.x.copy()
    except (OverflowError, FloatingPointError):  # the raised least-squares fit stands
        pass
    zeros, poles, gain = _params_to_zpk(theta, order)
    shortfall = np.max(target - _log_mag(zeros, poles, gain, w, dt))
    gain *= math.exp(max(shortfall, 0.0)) * (1.0 + 1e-9)
    return _zpk_to_ss(zeros, poles, gain, dt)


def control_sensitivity(G, C) -> ct.StateSpace:
    """Nominal control sensitivity ``V = -C/(1 + G C)`` of the single loop ``u = C (r - y)``, ``y = G u``:
    the transfer from a signal added to ``y`` to ``u``. Returned with every closed-loop state (no
    cancellation), so internal instability stays visible to :func:`h_lim`.

    Parameters
    ----------
    G : StateSpace or TransferFunction
        Nominal plant (SISO), input delay included.
    C : StateSpace or TransferFunction
        Controller in the same time domain.

    Returns
    -------
    StateSpace
        ``V``, with all closed-loop states.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> V = tune.control_sensitivity(ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1])))
    >>> round(float(ct.evalfr(V, 0).real), 4)               # -C/(1 + G C) at DC: -2/3
    -0.6667
    """
    G = _finite_ss(G, "G")
    C = _finite_ss(C, "C")
    _same_domain(G, C, "control_sensitivity")
    if G.ninputs != C.noutputs or G.noutputs != C.ninputs:
        raise DataError(f"dimension mismatch: G is {G.noutputs}x{G.ninputs}, C is {C.noutputs}x{C.ninputs}; "
                        "C must map G's outputs to G's inputs")
    return -ct.feedback(C, G)


def h_lim(W_delta, V_nom) -> float:
    """Robust-stability limit ``h_lim = 1 / ||W_delta V_nom||_inf`` (exact norm, SLICOT ab13dd).

    Parameters
    ----------
    W_delta : uncertainty shaping filter (p x m for the plant's p outputs, m inputs; SISO in ref. 000).
    V_nom : nominal control sensitivity (m x p), with all closed-loop states.

    Raises
    ------
    DataError
        when ``V_nom`` is unstable (the nominal closed loop is not stable, so no ``h`` is robust), on
        NaN entries, mismatched dimensions or time domains.

    Returns
    -------
    float
        The largest peak gain ``h`` of a stable ``Delta`` for which every ``G_nom + W_delta Delta`` is stabilised.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, C = ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1]))
    >>> V = tune.control_sensitivity(G, C)                  # -C/(1 + G C) = -2 (s + 1)/(s + 3)
    >>> round(tune.h_lim(ct.ss(ct.tf([0.5], [1])), V), 4)   # 1/||0.5 V|| = 1/(0.5 * 2)
    1.0
    """
    W = _finite_ss(W_delta, "W_delta")
    V = _finite_ss(V_nom, "V_nom")
    _same_domain(W, V, "h_lim")
    if W.noutputs != V.ninputs:
        raise DataError(f"dimension mismatch: W_delta has {W.noutputs} outputs but V_nom has {V.ninputs} inputs")
    if not lti.is_stable(V):
        raise DataError(f"the nominal closed loop is unstable (spectral abscissa {lti.spectral_abscissa(V):.4g}); "
                        "h_lim is only defined for a stabilising controller")
    if not lti.is_stable(W):
        raise DataError("W_delta must be stable")
    g, _ = lti.hinfnorm(ct.series(W, V))
    return 1.0 / g


@dataclasses.dataclass(frozen=True)
class HLim:
    """Result of :func:`h_lim_analysis`.

    Attributes
    ----------
    h_lim : float
        ``1 / ||W_delta V_nom||_inf``.
    peak_rad_s : float
        Frequency where ``|W_delta V_nom|`` peaks, rad/s (0 at DC).
    dc_ratio : float
        ``|W_delta V_nom|`` at DC over its peak (1: the peak is at DC).
    v_dc_is_minus_inv_g : bool or None
        ``V_nom(0) = -1/G(0)`` (to 1e-6): the controller has integral action on the loop, so at DC ``V`` does not
        depend on its gains. None when ``G`` was not given.
    sensitivity_at_peak : float or None
        ``|1 + V_nom G|`` at the peak frequency: the loop's sensitivity there (the transfer from the additive
        signal to the plant output). Where it is small the loops have high gain and ``V = -1/G (1 - S)``, so
        ``|W_delta V| = |W_delta| / |G|`` to within it, whatever the gains. None when ``G`` was not given.
    low_frequency_bound : bool
        The norm is set where the loop gain makes ``V = -1/G`` (``sensitivity_at_peak <= s_tol``; at DC with
        integral action it is 0): ``h_lim = |G| / |W_delta|`` at that frequency then ranks no controller that
        has that much loop gain there (a statement about the model's low-frequency uncertainty). Without ``G``
        a peak at DC alone sets it.
    """

    h_lim: float
    peak_rad_s: float
    dc_ratio: float
    v_dc_is_minus_inv_g: bool | None
    sensitivity_at_peak: float | None
    low_frequency_bound: bool

    def note(self) -> str:
        """One sentence for reports."""
        where = "DC" if self.peak_rad_s == 0.0 else f"{self.peak_rad_s:.3g} rad/s"
        if self.low_frequency_bound:
            return (f"h_lim = |G|/|W_delta| at {where}: ||W_delta V|| peaks where the loop gain makes V = -1/G "
                    "whatever the gains, so this is a controller-independent low-frequency bound")
        return f"||W_delta V|| peaks at {where}"


def _dc(sys) -> complex:
    s = lti.as_ss(sys)
    A, B, C, D = (np.asarray(M, float) for M in (s.A, s.B, s.C, s.D))
    if s.nstates == 0:
        return complex(D[0, 0])
    I = np.eye(A.shape[0])
    M = (I - A) if lti.is_discrete(s) else -A  # z = 1 or s = 0
    return complex((C @ np.linalg.solve(M, B) + D)[0, 0])


def h_lim_analysis(W_delta, V_nom, G=None, rel_tol: float = 1e-3, s_tol: float = 0.1) -> HLim:
    """:func:`h_lim` with where ``||W_delta V_nom||`` peaks and whether the value only bounds the model's
    low-frequency uncertainty.

    Parameters
    ----------
    W_delta, V_nom : as :func:`h_lim` (SISO).
    G : nominal plant as the loop sees it, input delay included (SISO, the time domain of ``V_nom``), optional:
        with it the result tells whether ``V_nom(0) = -1/G(0)`` (integral action) and the sensitivity
        ``|1 + V_nom G|`` at the peak.
    rel_tol : the peak counts as "at DC" when ``|W_delta V_nom|(0) >= (1 - rel_tol)`` times the norm.
    s_tol : the bound is controller-independent when the sensitivity at the peak is at most this: the gains
        then move h_lim by about that fraction at most (0.1: -20 dB of sensitivity, within 10 %). A peak just
        above DC (0.6 rad/s on the P2-A2's fifth-order test-bed models) is as controller-independent as one at DC.

    Returns
    -------
    HLim
        ``h_lim``, the peak frequency, the DC ratio, whether ``V_nom(0) = -1/G(0)``, the sensitivity at the peak
        and ``low_frequency_bound`` (the value bounds the model's uncertainty, not the gains).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, C = ct.ss(ct.tf([1.0], [1, 1])), ct.ss(ct.tf([2.0], [1]))    # plant 1/(s + 1), proportional gain 2

    >>> r = tune.h_lim_analysis(ct.ss(ct.tf([0.5], [1])), tune.control_sensitivity(G, C), G)
    >>> round(r.h_lim, 4), r.low_frequency_bound          # no integral action: S(0) = 1/3, not small
    (1.0, False)
    """
    h = h_lim(W_delta, V_nom)
    W, V = _finite_ss(W_delta, "W_delta"), _finite_ss(V_nom, "V_nom")
    if (W.noutputs, W.ninputs, V.noutputs, V.ninputs) != (1, 1, 1, 1):
        raise DataError("h_lim_analysis handles SISO W_delta and V_nom")
    g, w_pk = lti.hinfnorm(ct.series(W, V))
    dc_ratio = abs(_dc(W) * _dc(V)) / g
    at_dc = dc_ratio >= 1.0 - rel_tol
    peak = 0.0 if at_dc else float(w_pk)
    v_inv, sens = None, None
    if G is not None:
        Gs = _finite_ss(G, "G")
        _same_domain(Gs, V, "h_lim_analysis")
        s_dc = abs(_dc(V) * _dc(Gs) + 1.0)
        v_inv = bool(s_dc < 1e-6)
        if peak == 0.0:
            sens = s_dc
        elif math.isfinite(peak):  # a continuous norm reached at infinite frequency has no loop gain there
            w1 = np.array([peak])
            sens = abs(complex(lti.freqresp(V, w1)[0, 0, 0]) * complex(lti.freqresp(Gs, w1)[0, 0, 0]) + 1.0)
    low = bool(at_dc) if sens is None else bool(sens <= s_tol)
    return HLim(h_lim=float(h), peak_rad_s=peak, dc_ratio=float(dc_ratio), v_dc_is_minus_inv_g=v_inv,
                sensitivity_at_peak=None if sens is None else float(sens), low_frequency_bound=low)
