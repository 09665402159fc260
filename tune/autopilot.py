"""Structured H-inf tuning of an autopilot's own attitude and rate loops (PX4, ArduPilot) on all three axes.

The structure tuned is the autopilot's law as it flies, at its loop rate with its filters in the loop: the angle
P and the rate law of :mod:`rotorlab.autopilots` (``rate_controller_lti(..., fixed_structure=True)``, gyro
low-pass, D-term or error/derivative filters, yaw's torque low-pass), per axis. The gains tuned are the angle P
and the rate P, I and D (PX4: ``MC_*_P``, ``MC_*RATE_P/I/D`` with ``MC_*RATE_K = 1``; ArduPilot:
``ATC_ANG_*_P``, ``ATC_RAT_*_P/I/D``); filter cutoffs and feed-forward stay as the start parameters have them
(feed-forward shapes set-point tracking only, none of the goals).

The plant of an axis is ``u -> [rate, angle]`` (normalised torque in, rad/s and rad out), discrete at the loop
period with its input delay. A model at another sample time or with a delay that is not a whole number of loop
periods is converted exactly: back to continuous time (inverse ZOH), the angle added as the integral of the
rate, then re-sampled at the loop period by the modified z-transform of a zero-order-held input delayed by a
fraction of a period (:func:`rotorlab.lti.c2d_zoh_delay`). That is exact at the sample instants, for the input
an autopilot really applies (held torque), where a Pade or Thiran section approximates the delay of a band-limited
signal and adds its own phase error near Nyquist; the cost is one state more than the whole-sample shift register.

Goals are those of :mod:`rotorlab.tune.goals` (crossover band, disk margin, rejection, effort) on the cascade's
generalised plant (:func:`rotorlab.tune.cascade.generalised_plant`; signals ``d_u`` torque disturbance at the
plant input, ``n_q`` gyro noise, ``theta`` angle, ``u`` plant input, ``u_ctrl`` command), as the generic
multirotor spec of :mod:`rotorlab.tune.autopilot_spec` derives them from the plant; the engine is the one
:func:`rotorlab.tune.goals.tune_cascade` runs.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.autopilots import get as get_autopilot
from rotorlab.errors import ConfigError, DataError
from rotorlab.tune import cascade as cas
from rotorlab.tune import goals as G
from rotorlab.tune.blocks import Block, Param, Structure
from rotorlab.tune.hinfstruct import SPEC_SUB_ITER, StartFailure, _Problem, closed_loop, run_starts
from rotorlab.tune.margins import crossover_frequencies, margins

__all__ = ["AXES", "tuned_names", "axis_plant", "AutopilotAxisBlock", "margins_goal", "analyse_axis",
           "AxisAnalysis", "tune_axis", "tune_autopilot", "AxisTuneResult", "evaluate_axis", "parallel_gains",
           "apply_gains", "px4_autotune_params", "disturbance_response", "FILTER_FACTORS", "filter_candidates",
           "tune_filters", "FilterSearch", "px4_autotune_settings", "baseline_sets", "tuned_parameters",
           "parameter_file_header"]

AXES = ("roll", "pitch", "yaw")


def tuned_names(autopilot, axis: str) -> dict[str, str]:
    """Role -> parameter name of the gains tuned on ``axis``: ``ANG_P, P, I, D``."""
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    n = ap.axis_names(axis)
    return {k: n[k] for k in ("ANG_P", "P", "I", "D")}


def axis_plant(G, delay_s: float, dt_s: float) -> ct.StateSpace:
    """``u -> [rate, angle]`` of one axis, discrete at ``dt_s`` with the input delay ``delay_s`` (any value).

    Parameters
    ----------
    G : LTI
        Rate response to the normalised torque (rad/s per unit), continuous or discrete at any sample time, delay
        removed, strictly proper.
    delay_s : float
        Input delay, s; need not be a whole number of ``dt_s`` (exact modified z-transform, see the module).
    dt_s : float
        Loop period, s.

    Examples
    --------
    >>> import control as ct
    >>> P = axis_plant(ct.tf([50.0], [1.0, 0.0]), 0.0281, 1 / 400)   # 11.24 periods of delay
    >>> P.noutputs, P.ninputs, P.dt
    (2, 1, 0.0025)
    """
    G = lti.as_ss(G)
    if G.ninputs != 1 or G.noutputs != 1:
        raise ValueError(f"the axis model must be SISO torque -> rate, got {G.noutputs}x{G.ninputs}")
    if lti.is_discrete(G):
        G = lti.d2c_zoh(G)
    A, B, C, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
    if np.any(D):
        raise ValueError("the axis model must be strictly proper (a rate responds to a torque through inertia)")
    n = A.shape[0]
    Aa = np.block([[A, np.zeros((n, 1))], [C, np.zeros((1, 1))]])
    Ba = np.vstack([B, np.zeros((1, 1))])
    Ca = np.block([[C, np.zeros((1, 1))], [np.zeros((1, n)), np.ones((1, 1))]])
    return lti.c2d_zoh_delay(ct.ss(Aa, Ba, Ca, np.zeros((2, 1))), dt_s, delay_s)


class AutopilotAxisBlock(Block):
    """One axis of an autopilot's cascade as a tunable block.

    It reads ``[angle_sp, angle, rate_sp, rate]`` (the measurements of
    :func:`rotorlab.tune.cascade.generalised_plant`) and drives ``[rate_sp_cmd, torque]``: ``rate_sp_cmd =
    ANG_P (angle_sp - angle)`` and the autopilot's rate law from ``(rate_sp, rate)``. Parameters are the
    autopilot's names of :func:`tuned_names`; the matrices are affine in them (``fixed_structure`` realisation),
    so their derivatives are constant and exact.
    """

    def __init__(self, autopilot, params: Mapping[str, float], axis: str, dt_s: float):
        ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
        self.ap, self.axis, self._dt_s = ap, axis, float(dt_s)
        self.roles = tuned_names(ap, axis)
        base = dict(params)
        if ap.NAME == "px4":
            base[ap.axis_names(axis)["K"]] = 1.0  # the tuned P, I, D are PX4's parallel form (K = 1)
        names = list(self.roles.values())
        zero = {**base, **{n: 0.0 for n in names}}
        self._m0 = self._one(zero)
        self._dm = []
        for n in names:
            m1 = self._one({**zero, n: 1.0})
            self._dm.append(tuple(a - b for a, b in zip(m1, self._m0)))
        # the realisation must be affine in the gains: a point with every gain set reproduces M0 + sum theta dM
        probe = {**zero, **{n: 0.3 + 0.1 * i for i, n in enumerate(names)}}
        want = self._one(probe)
        got = self._affine([probe[n] for n in names])
        if not all(np.allclose(a, b, atol=1e-9) for a, b in zip(want, got)):
            raise ValueError(f"{ap.NAME} {axis}: the fixed-structure law is not affine in {names}")
        super().__init__(f"{ap.NAME}_{axis}", [Param(n, float(base[n]), lower=0.0) for n in names],
                         4, 2, self._m0[0].shape[0], dt_s)


    def __getstate__(self):
        # a module does not pickle: the autopilot travels to run_starts' worker processes by its registry name
        return {**self.__dict__, "ap": self.ap.NAME}

    def __setstate__(self, state):
        self.__dict__.update(state, ap=get_autopilot(state["ap"]))
    def _one(self, params):
        C = self.ap.rate_controller_lti(params, self.axis, self._dt_s, fixed_structure=True)
        Ar, Br, Cr, Dr = (np.asarray(M, float) for M in (C.A, C.B, C.C, C.D))
        nr = Ar.shape[0]
        p = float(params[self.roles["ANG_P"]])
        B = np.hstack([np.zeros((nr, 2)), Br])
        Cm = np.vstack([np.zeros((1, nr)), Cr])
        D = np.array([[p, -p, 0.0, 0.0], [0.0, 0.0, Dr[0, 0], Dr[0, 1]]])
        return Ar, B, Cm, D

    def _affine(self, theta):
        return tuple(m0 + sum(t * dm[j] for t, dm in zip(theta, self._dm)) for j, m0 in enumerate(self._m0))

    def matrices(self, theta):
        return self._affine(np.asarray(theta, float))

    def matrix_derivatives(self, theta, idx):
        return [self._dm[i] for i in idx]



# ------------------------------------------------------------------------------------------------- goals -------
def margins_goal(alpha: float, hard: bool = True) -> G.Margins:
    """The balanced disk-margin floor ``alpha`` at the plant input as a :class:`rotorlab.tune.goals.Margins`
    goal: the gain and phase margins a disk of size ``alpha`` guarantees, ``GM = (2 + alpha) / (2 - alpha)``,
    ``PM = 2 atan(alpha / 2)``, both giving ``alpha_req = alpha``."""
    g = (2.0 + alpha) / (2.0 - alpha)
    return G.Margins("u", 20.0 * math.log10(g), math.degrees(2.0 * math.atan(alpha / 2.0)), hard=hard)


# ---------------------------------------------------------------------------------------------- analysis -------
@dataclasses.dataclass
class AxisAnalysis:
    """Linear analysis of one axis at the loop rate (disturbance ``d_u`` in normalised torque, angle in rad).

    ``dist_peak_rad`` and ``dist_iae_rad_s``: peak and IAE (over ``horizon_s``) of the angle after a unit-step
    torque disturbance at the plant input (both scale with the step); ``dist_hinf``: peak gain ``|theta / d_u|``;
    ``disk_alpha``, ``gm_db``, ``pm_deg``: margins with both loops broken at the plant input; ``wc_rad_s``:
    gain crossovers there; ``noise_gain``: peak ``|u_ctrl / n_q|``; ``stable``."""

    stable: bool
    dist_peak_rad: float
    dist_iae_rad_s: float
    dist_hinf: float
    disk_alpha: float
    gm_db: float
    pm_deg: float
    wc_rad_s: tuple
    noise_gain: float


def _closed(autopilot, params, axis, Gp, inputs, outputs):
    blk = AutopilotAxisBlock(autopilot, apply_gains(autopilot, params, axis, parallel_gains(autopilot, params, axis)), axis,
                 float(Gp.dt))
    K = blk.ss()
    return closed_loop(cas.generalised_plant(Gp, (), inputs=inputs, outputs=outputs), cas.N_MEAS, cas.N_CON, K), K


def disturbance_response(autopilot, params, axis: str, Gp, horizon_s: float = 2.0) -> np.ndarray:
    """Angle (rad) after a unit-step torque disturbance at the plant input, samples at the loop period."""
    T, _ = _closed(autopilot, params, axis, Gp, ("d_u",), ("theta",))
    n = int(round(horizon_s / float(Gp.dt)))
    A, B, C, D = (np.asarray(M, float) for M in (T.A, T.B, T.C, T.D))
    x = np.zeros(A.shape[0])
    y = np.empty(n)
    for k in range(n):
        y[k] = C[0] @ x + D[0, 0]
        x = A @ x + B[:, 0]
    return y


def analyse_axis(autopilot, params: Mapping[str, float], axis: str, Gp, horizon_s: float = 2.0) -> AxisAnalysis:
    """:class:`AxisAnalysis` of ``params`` (the autopilot's names and units) around ``Gp`` (:func:`axis_plant`).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab.autopilots import px4
    >>> Gp = axis_plant(ct.tf([100.0], [1 / 27.0, 1.0, 0.0]), 0.028, 1 / 250)
    >>> a = analyse_axis("px4", px4.TABLE.defaults(), "pitch", Gp)
    >>> a.stable, round(a.disk_alpha, 2)
    (True, 0.49)
    """
    dt = float(Gp.dt)
    T, K = _closed(autopilot, params, axis, Gp, ("d_u", "n_q"), ("theta", "u_ctrl"))
    if not lti.is_stable(T):
        return AxisAnalysis(False, math.inf, math.inf, math.inf, 0.0, 0.0, 0.0, (), math.inf)
    y = disturbance_response(autopilot, params, axis, Gp, horizon_s)
    dist_hinf = lti.hinfnorm(T[0, 0])[0]
    noise = lti.hinfnorm(T[1, 1])[0]
    L = -closed_loop(cas.generalised_plant(Gp, {"u"}, inputs=("d_u",), outputs=("u_ctrl",)), cas.N_MEAS, cas.N_CON, K)
    w = np.geomspace(1e-2, math.pi / dt * (1 - 1e-10), 800)
    m = margins(L, w=w)
    wc = tuple(float(x) for x in crossover_frequencies(L, w=w))
    return AxisAnalysis(True, float(np.max(np.abs(y))), float(np.sum(np.abs(y)) * dt), float(dist_hinf),
                        float(m.disk_alpha), float(m.gm_db), float(m.pm_deg), wc, float(noise))


# ------------------------------------------------------------------------------------------------ tuning -------
@dataclasses.dataclass
class AxisTuneResult:
    """Tuned gains of one axis (the autopilot's names; PX4's with ``K = 1``), every goal's result
    (:class:`rotorlab.tune.goals.GoalResult`, value <= 1 meets it), the objective (largest soft goal), the
    per-start merits and the wall time."""

    axis: str
    gains: dict
    report: list
    objective: float
    starts: list
    time_s: float

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.report if r.hard)


def parallel_gains(autopilot, params: Mapping[str, float], axis: str) -> dict[str, float]:
    """The tuned gains of ``axis`` as the tuner's structure holds them: PX4's ``K P, K I, K D`` (the
    parallel form, ``K = 1``), ArduPilot's as they are; plus the angle P."""
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    roles = tuned_names(ap, axis)
    k = float(params[ap.axis_names(axis)["K"]]) if ap.NAME == "px4" else 1.0
    return {n: float(params[n]) * (1.0 if r == "ANG_P" else k) for r, n in roles.items()}


def apply_gains(autopilot, params: Mapping[str, float], axis: str, gains: Mapping[str, float]) -> dict:
    """``params`` with the tuned ``gains`` of ``axis`` in place (PX4: and ``MC_*RATE_K = 1``, the form the gains
    are tuned in).

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> p = apply_gains("px4", px4.TABLE.defaults(), "roll", {"MC_ROLLRATE_P": 0.2})
    >>> p["MC_ROLLRATE_P"], p["MC_ROLLRATE_K"]
    (0.2, 1.0)
    """
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    p = {**params, **gains}
    if ap.NAME == "px4":
        p[ap.axis_names(axis)["K"]] = 1.0
    return p


def evaluate_axis(autopilot, params: Mapping[str, float], axis: str, Gp, goals) -> list:
    """Every goal of ``goals`` (:mod:`rotorlab.tune.goals` objects) for ``params`` around ``Gp``."""
    dt = float(Gp.dt)
    blk = AutopilotAxisBlock(autopilot, apply_gains(autopilot, params, axis, parallel_gains(autopilot, params, axis)), axis, dt)
    S = Structure([blk])
    th = S.values
    K = S.ss(th)
    stable = lti.is_stable(closed_loop(cas.generalised_plant(Gp), cas.N_MEAS, cas.N_CON, K))
    per_goal = [(g, g.channels(Gp, dt)) for g in goals]
    chans = [c for _, cs in per_goal for c in cs]
    out, i = [], 0
    peaks = _Problem(S, chans, [], np.zeros(len(th), bool), np.ones(0)).all_peaks(th, nmax=3) if stable else []
    for g, cs in per_goal:
        if stable:
            v = max((p[0][0] for p in peaks[i:i + len(cs)]), default=0.0)
            det = g.detail(Gp, K)
        else:
            v, det = math.inf, "closed loop unstable"
        i += len(cs)
        out.append(G.GoalResult(g.label, axis, float(v), 1.0, bool(v <= 1.0), g.hard, det))
    return out


def tune_axis(autopilot, params: Mapping[str, float], axis: str, Gp, goals, *, starts: int = 1, seed=0,
              max_iter: int = 30, tol: float = 1e-3, n_jobs: int = 1, executor=None,
              time_limit_s=None) -> AxisTuneResult:
    """Tune the angle P and rate P, I, D of one axis on ``Gp`` (:func:`axis_plant`) against ``goals``.

    The engine is the one :func:`rotorlab.tune.goals.tune_cascade` runs (structured H-inf, soft goals minimised,
    hard goals constrained, stabilisation phase first), with the autopilot's law at the loop rate as the structure.
    ``params`` gives the start gains and every parameter that is not tuned (filters); a start that does not
    stabilise the loop is stabilised first. Starts after the first are seeded perturbations of it.
    """
    t0 = time.perf_counter()
    dt = float(Gp.dt)
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    p = apply_gains(ap, params, axis, parallel_gains(ap, params, axis))
    blk = AutopilotAxisBlock(ap, p, axis, dt)
    S = Structure([blk])
    th0 = S.values
    lower = np.array([max(0.0, ap.TABLE[n].min or 0.0) for n in blk.roles.values()])
    upper = np.array([_upper(ap, n) for n in blk.roles.values()])
    th0 = np.clip(th0, lower, upper)
    channels, poles = [], None
    for g in goals:
        channels += g.channels(Gp, dt)
        if isinstance(g, G.Poles):
            poles = (g.min_decay, g.min_damping)
    stab = [(cas.generalised_plant(Gp), cas.N_MEAS, cas.N_CON)]
    free = np.ones(len(th0), bool)
    prob = _Problem(S, channels, stab, free, np.maximum(np.abs(th0), 1e-3), poles=poles)
    results = run_starts(prob, th0, lower, upper, starts=starts, seed=seed, n_jobs=n_jobs, max_iter=max_iter,
                         tol=tol, time_limit_s=time_limit_s, spread=0.3, executor=executor,
                         sub_iter=SPEC_SUB_ITER, sampling=False)
    best, best_key, per_start = None, None, []
    for r in results:
        if isinstance(r, StartFailure):
            per_start.append(math.inf)
            continue
        merit = r[1]
        per_start.append(float(merit[1]) if merit[0] <= 1e-9 else math.inf)
        key = (merit[0] > 1e-9, merit[0], merit[1])
        if best_key is None or key < best_key:
            best, best_key = r, key
    if best is None:
        raise ValueError(f"{ap.NAME} {axis}: no start stabilises the loop; start from parameters that do")
    # the engine holds the bounds in its scaled variables: a gain on a bound comes back a few ulp past it
    # (ATC_ANG_RLL_P 12.000000000000002), which the parameter file's range check refuses
    gains = dict(zip(blk.roles.values(), map(float, np.clip(best[0], lower, upper))))
    rep = evaluate_axis(ap, apply_gains(ap, params, axis, gains), axis, Gp, goals)
    return AxisTuneResult(axis, gains, rep, G.objective(rep), per_start, time.perf_counter() - t0)


def _upper(ap, name):
    hi = ap.TABLE[name].max
    return math.inf if hi is None else float(hi)


def tune_autopilot(spec, plants: Mapping[str, ct.StateSpace], params: Mapping[str, float], *, starts: int = 1,
                   seed=0, max_iter: int = 30, n_jobs: int = 1, executor=None) -> dict:
    """Tune every axis of an :class:`rotorlab.tune.spec.AutopilotSpec` on ``plants`` (axis -> :func:`axis_plant`
    at ``spec.dt``), starting from and keeping the filters of ``params``. Returns axis -> :class:`AxisTuneResult`.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab.autopilots import px4
    >>> from rotorlab.tune.autopilot_spec import generic_spec
    >>> from rotorlab.tune.spec import parse_spec
    >>> import tomllib
    >>> dt = 1 / 250
    >>> Gp = axis_plant(ct.tf([1 / 0.02], [1 / 27.0, 1.0, 0.0]), 0.026, dt)  # inertia, motor lag, 6.5 periods
    >>> p = px4.TABLE.defaults()
    >>> G = ct.tf([1 / 0.02], [1 / 27.0, 1.0, 0.0])
    >>> spec = parse_spec(tomllib.loads(generic_spec("px4", {"pitch": (Gp, G, 0.026)}, dt, p, {"defaults": p})))
    >>> res = tune_autopilot(spec, {"pitch": Gp}, p)
    >>> res["pitch"].passed
    True
    """
    out = {}
    for axis in spec.axes:
        if axis not in plants:
            raise ValueError(f"the spec tunes {axis} but no plant was given for it")
        Gp = plants[axis]
        if abs(float(Gp.dt) - spec.dt) > 1e-12:
            raise ValueError(f"{axis}: the plant's sample time {Gp.dt} s is not the spec's loop period {spec.dt} s")
        out[axis] = tune_axis(spec.autopilot, params, axis, Gp, spec.goals[axis], starts=starts, seed=seed,
                              max_iter=max_iter, n_jobs=n_jobs, executor=executor)
    return out


#: the factors on each filter group's cutoffs a search tries (:func:`filter_candidates`): the flown setting and
#: up to 2.5 times it, where the gyro noise a faster filter passes is bounded by the spec's effort goal
FILTER_FACTORS = (1.0, 1.5, 2.0, 2.5)
#: a cutoff is kept at most this fraction of the Nyquist frequency: at it the discrete Butterworth's response is
#: no longer the analogue filter's, and PX4 switches a filter at or above Nyquist off (filters.butter2_on)
MAX_NYQUIST_FRACTION = 0.8


def filter_candidates(autopilot, params: Mapping[str, float], dt_s: float,
                      factors=FILTER_FACTORS) -> list[dict[str, float]]:
    """The filter settings a search tries: every combination over the autopilot's ``FILTER_GROUPS`` of each
    group's cutoffs in ``params`` times a factor of ``factors``, capped at :data:`MAX_NYQUIST_FRACTION` of the
    loop's Nyquist frequency and at the parameter's documented maximum; a filter that is off (0 Hz) stays off.
    The first candidate is ``params``' own setting; duplicates (after capping) are dropped.

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> c = filter_candidates("px4", px4.TABLE.defaults(), 1 / 250)
    >>> len(c), c[0], c[-1]
    (16, {'IMU_GYRO_CUTOFF': 40.0, 'IMU_DGYRO_CUTOFF': 20.0}, {'IMU_GYRO_CUTOFF': 100.0, 'IMU_DGYRO_CUTOFF': 50.0})
    """
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    cap = MAX_NYQUIST_FRACTION * 0.5 / dt_s
    per_group = []
    for group in ap.FILTER_GROUPS:
        options = []
        for f in factors:
            setting = {n: min(float(params[n]) * f, cap, math.inf if ap.TABLE[n].max is None else ap.TABLE[n].max)
                       if float(params[n]) > 0 else 0.0 for n in group}
            if setting not in options:
                options.append(setting)
        per_group.append(options)
    out = [{}]
    for options in per_group:
        out = [{**a, **b} for a in out for b in options]
    return out


@dataclasses.dataclass
class FilterSearch:
    """:func:`tune_filters`' result: the chosen filter setting, its per-axis :class:`AxisTuneResult`, and per
    candidate ``(setting, worst axis objective, all hard goals met)``."""

    filters: dict
    results: dict
    table: list


def tune_filters(make_spec, plants: Mapping[str, ct.StateSpace], params: Mapping[str, float], candidates,
                 **tune_kw) -> FilterSearch:
    """Tune the gains at each filter setting of ``candidates`` (:func:`filter_candidates`) and keep the setting
    whose tuned set meets every hard goal on every axis with the smallest worst-axis objective (the largest soft
    goal of the worst axis); with none feasible, the smallest number of failed hard goals, then the objective.

    ``make_spec(params) -> AutopilotSpec`` gives the spec for a parameter set (the generic spec's band and the
    D path's lag depend on the filters); ``tune_kw`` go to :func:`tune_autopilot`.

    Examples
    --------
    >>> found = tune_filters(lambda p: spec, plants, params, filter_candidates("px4", params, 1 / 250))  # doctest: +SKIP
    >>> found.filters  # doctest: +SKIP
    """
    best, best_key, table = None, None, []
    for setting in candidates:
        p = {**params, **setting}
        res = tune_autopilot(make_spec(p), plants, p, **tune_kw)
        failed = sum(1 for r in res.values() for x in r.report if x.hard and not x.passed)
        worst = max(r.objective for r in res.values())
        table.append((setting, worst, failed == 0))
        key = (failed, worst)
        if best_key is None or key < best_key:
            best, best_key = (setting, res), key
    return FilterSearch(best[0], best[1], table)


def px4_autotune_params(plants: Mapping[str, ct.StateSpace], params: Mapping[str, float], *,
                        rise_time_s: float | None = None,
                        amplitude: float | None = None) -> tuple[dict[str, float], dict[str, str]]:
    """The parameters PX4's autotune module saves when run on ``plants`` (axis -> :func:`axis_plant`) flying
    ``params``: the module's identification (:func:`rotorlab.autopilots.px4_autotune.identify_axis`) on the
    linear closed loop at the loop period, the signal added to the rate set-point, then its design and its
    check of the set. Returns the saved parameters and, per axis, why PX4 would not save them; PX4 saves all
    axes or none (then the first dict is empty and the flown gains stay on every axis).

    ``rise_time_s`` is MC_AT_RISE_TIME (default 0.14 s; yaw always 0.2 s), ``amplitude`` MC_AT_SYSID_AMP
    (default 0.7 rad/s; the loop is linear, so it changes only the time to convergence)."""
    from rotorlab.autopilots import filters, px4, px4_autotune

    kw = {} if rise_time_s is None else {"rise_time_s": rise_time_s}
    amp = px4_autotune.SYSID_AMP_DEFAULT if amplitude is None else float(amplitude)
    cutoff = float(params["IMU_GYRO_CUTOFF"])
    results, rejected = {}, {}
    for axis, Gp in plants.items():
        dt = float(Gp.dt)
        T = _rate_sp_loop(px4, params, axis, Gp)
        Fg = filters.butter2_ss(1.0 / dt, cutoff)
        A, B, C, D = (np.asarray(M, float) for M in (T.A, T.B, T.C, T.D))
        Af, Bf, Cf, Df = (np.asarray(M, float) for M in (Fg.A, Fg.B, Fg.C, Fg.D))
        x, xf = np.zeros(A.shape[0]), np.zeros(Af.shape[0])

        def loop(r, A=A, B=B, C=C, D=D, Af=Af, Bf=Bf, Cf=Cf, Df=Df):
            nonlocal x, xf
            u, q = C @ x + D[:, 0] * r
            y = float(Cf[0] @ xf + Df[0, 0] * q)
            x = A @ x + B[:, 0] * r
            xf = Af @ xf + Bf[:, 0] * q
            return float(u), y

        n = px4.axis_names(axis)
        scale = 1.0 / (float(params[n["P"]]) * float(params[n["K"]]))
        try:
            results[axis] = px4_autotune.identify_axis(loop, axis, dt, cutoff, scale, amplitude=amp, **kw)
        except DataError as exc:
            rejected[axis] = str(exc)
    if rejected:
        return {}, rejected
    try:
        return px4_autotune.autotune_params(results), {}
    except DataError as exc:
        return {}, {a: str(exc) for a in results}


def _rate_sp_loop(autopilot, params, axis, Gp):
    """The closed loop of ``params`` around ``Gp`` from a signal added to the rate set-point (after the angle
    P, where PX4's autotune adds its signal) to ``[u, q]``: torque set-point and body rate."""
    blk = AutopilotAxisBlock(autopilot, apply_gains(autopilot, params, axis, parallel_gains(autopilot, params, axis)),
                             axis, float(Gp.dt))
    P = cas.generalised_plant(Gp, (), inputs=("d_u",), outputs=("u", "q"))
    B = np.asarray(P.B, float).copy()
    D = np.asarray(P.D, float).copy()
    B[:, 0] = 0.0
    D[:, 0] = 0.0
    D[2 + 2, 0] = 1.0  # measurements [theta_ref, theta_meas, q_ref, q_meas] follow the two outputs
    return closed_loop(ct.ss(P.A, B, P.C, D, P.dt), cas.N_MEAS, cas.N_CON, blk.ss())


#: PX4 autotune's settings a parameter set may carry: name, px4_autotune_params keyword, documented range
#: (mc_autotune_attitude_control_params.c)
PX4_AUTOTUNE_SETTINGS = (("MC_AT_RISE_TIME", "rise_time_s", 0.01, 0.5), ("MC_AT_SYSID_AMP", "amplitude", 0.1, 6.0))


def px4_autotune_settings(raw: Mapping[str, float], source=None) -> dict[str, float]:
    """The keywords of :func:`px4_autotune_params` that the flown parameters ``raw`` carry (MC_AT_RISE_TIME,
    MC_AT_SYSID_AMP), range-checked as PX4 documents them; absent ones keep the module's defaults.

    Raises
    ------
    rotorlab.errors.ConfigError
        A value outside PX4's range, naming ``source`` (the file or log), the parameter and the range.

    Examples
    --------
    >>> px4_autotune_settings({"MC_AT_RISE_TIME": 0.2, "MC_ROLL_P": 6.5})
    {'rise_time_s': 0.2}
    """
    out = {}
    for name, key, lo, hi in PX4_AUTOTUNE_SETTINGS:
        if name in raw:
            v = float(raw[name])
            if not lo <= v <= hi:
                raise ConfigError("value outside PX4's documented range", file=source, field=name,
                                  expected=f"{lo:g} <= {name} <= {hi:g} (mc_autotune_attitude_control_params.c)",
                                  got=v)
            out[key] = v
    return out


def baseline_sets(autopilot, plants: Mapping[str, ct.StateSpace], current: Mapping[str, float],
                  flown_name: str | None = None, autotune: Mapping[str, float] | None = None
                  ) -> tuple[dict[str, dict], dict[str, str]]:
    """The parameter sets a user has today, to compare a tuned set with: ``current`` under ``flown_name`` where
    it was flown (a log's or a file's parameters; None: ``current`` is the defaults), the autopilot's defaults
    and, for PX4, the set its autotune module saves flying ``current`` on ``plants`` (:func:`px4_autotune_params`
    with the ``autotune`` keywords of :func:`px4_autotune_settings`). Returns the sets in that order and, per
    axis, why PX4's autotune would not save its gains (then that baseline is ``current``: PX4 saves all axes or
    none).

    Examples
    --------
    >>> from rotorlab.autopilots import ardupilot
    >>> sets, rejected = baseline_sets("ardupilot", {}, ardupilot.TABLE.defaults())
    >>> list(sets), rejected
    (['defaults'], {})
    """
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    sets = {flown_name: dict(current)} if flown_name else {}
    sets["defaults"] = ap.TABLE.defaults()
    rejected: dict[str, str] = {}
    if ap.NAME == "px4":
        gains, rejected = px4_autotune_params(plants, current, **dict(autotune or {}))
        sets["px4-autotune"] = {**current, **gains}
    return sets, rejected


def tuned_parameters(autopilot, gains: Mapping[str, Mapping[str, float]],
                     filters: Mapping[str, float] | None = None) -> dict[str, float]:
    """The parameters to write for tuned ``gains`` (axis -> name -> value) and chosen ``filters``: the gains as
    tuned, PX4's ``MC_*RATE_K = 1`` for each tuned axis (the parallel form the gains are tuned in, :func:`apply_gains`).

    Examples
    --------
    >>> tuned_parameters("px4", {"roll": {"MC_ROLLRATE_P": 0.2}})
    {'MC_ROLLRATE_P': 0.2, 'MC_ROLLRATE_K': 1.0}
    """
    out = dict(filters or {})
    for axis, g in gains.items():
        out.update(apply_gains(autopilot, {}, axis, g))
    return out


def parameter_file_header(lines, failed) -> str:
    """A tuned parameter file's header: ``lines`` (what was tuned against which goals), led where ``failed``
    (labels of hard goals not met) is not empty by the failure and "do not fly these parameters".

    Examples
    --------
    >>> print(parameter_file_header(["roll tuned"], ["roll margins"]))
    FAILED: hard goals not met: roll margins
    do not fly these parameters
    roll tuned
    """
    head = [f"FAILED: hard goals not met: {'; '.join(failed)}", "do not fly these parameters"] if failed else []
    return "\n".join([*head, *lines])
