"""systune-like tuning goals on the attitude cascade, their evaluation and the goal-aware tuner.

Every goal becomes one or more weighted channels of the cascade's generalised plant (see
:mod:`rotorlab.tune.cascade`); a channel's value is a normalised peak over frequency, so a goal passes when
its value is <= 1. Soft goals are minimised (their maximum is the objective), hard goals constrained.

* ``Tracking``: systune's relative tracking error ``|1 - T(jw)| <= |MaxError(jw)|`` with
  ``MaxError = (peak s + wc dc) / (s + wc)``, ``wc = 2 / response_time`` (MATLAB TuningGoal.Tracking).
* ``CrossoverBand``: with the loop opened at the point, ``|L| >= 1`` below ``wc_min`` and ``|L| <= 1`` above
  ``wc_max``: every gain crossover lies in the band. Value: the worse of ``max 1/|L|`` below the band and
  ``max |L|`` above it.
* ``Sensitivity``: closed-loop sensitivity at a point below a maximum-gain profile.
* ``Rejection`` / ``Gain``: closed-loop gain from an input to an output below a maximum-gain profile.
* ``Effort``: gain from ``theta_ref`` to the controller command below a bound.
* ``Margins``: balanced disk margin (Seiler et al. 2020) at a point at least the one implied by the
  gain/phase margins: value ``alpha_req * ||S - 1/2||_inf``.
* ``Poles``: closed-loop poles with at least ``min_damping`` and ``min_decay`` (1/s); hard constraint.
"""

from __future__ import annotations

import dataclasses
import math
import time

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.config import REQUIRED, Table, _is_number
from rotorlab.errors import ConfigError
from rotorlab.gains import GainSet
from rotorlab.tune import cascade as cas
from rotorlab.tune.hinfstruct import SPEC_SUB_ITER, Channel, StartFailure, _Problem, closed_loop, run_starts
from rotorlab.tune.margins import crossover_frequencies, margins

__all__ = ["GOAL_TYPES", "Goal", "Tracking", "CrossoverBand", "Sensitivity", "Rejection", "Effort", "Margins", "Poles",
           "GoalResult", "highpass_max_gain", "evaluate", "tune_cascade", "TuneResult", "format_report"]


def highpass_max_gain(order: int, gain_db: float, corner_rad_s: float) -> ct.TransferFunction:
    """Maximum-gain profile ``g (s/wc)^n / (s/wc + 1)^n``: ``gain_db`` above the corner, rolling off at
    ``20 n`` dB/decade below it."""
    g = 10 ** (gain_db / 20)
    num = np.zeros(order + 1)
    num[0] = g / corner_rad_s**order
    den = np.poly1d([1.0 / corner_rad_s, 1.0]) ** order
    return ct.tf(num, den.coeffs)


class _InvMag:
    """``w -> 1/|W(jw)|`` for a SISO continuous weight (a maximum-gain profile), by polynomial evaluation.

    A class rather than a closure so goals pickle into worker processes."""

    def __init__(self, W):
        if isinstance(W, (int, float)):
            W = ct.tf([float(W)], [1.0])
        W = ct.tf(W) if not isinstance(W, ct.TransferFunction) else W
        self.num = np.asarray(W.num[0][0], float)
        self.den = np.asarray(W.den[0][0], float)

    def __call__(self, w):
        s = 1j * np.asarray(w, float)
        return np.abs(np.polyval(self.den, s)) / np.maximum(np.abs(np.polyval(self.num, s)), 1e-300)


class _Const:
    def __init__(self, a):
        self.a = float(a)

    def __call__(self, w):
        return np.full(np.size(w), self.a)


_inv = _InvMag


def _detail_grid(Gp):
    """Frequency grid (rad/s) for the report details of discrete loops: 600 log points up to Nyquist.

    The delay's shift register makes the loop's A defective, so rotorlab.tune.margins falls back to one
    dense solve per frequency; its default 4000-point grid then costs more than the whole tuning. Crossings
    are refined by brentq on the exact response, so the grid only has to separate them (0.9 % spacing).
    The grid stops 1e-10 (relative) short of Nyquist: there Im L is pure round-off, whose sign can differ
    between the gridded and the pointwise evaluation and break the bracketing; margins still treats the
    end point as Nyquist (it compares with math.isclose)."""
    if not lti.is_discrete(Gp):
        return None
    return np.geomspace(1e-3, math.pi / float(Gp.dt) * (1 - 1e-10), 600)


class Goal:
    hard: bool = False
    label: str = "goal"

    @staticmethod
    def from_toml(g: Table) -> Goal:
        """One ``[[goal]]`` table (a strict :class:`rotorlab.config.Table`): the reader registered for its ``type``
        in :data:`GOAL_TYPES` reads the keys that type accepts, the only ones it accepts. An optional ``name``
        replaces the label built from the type and signals (reports key results by label: two goals on one
        channel, e.g. a peak and a frequency-weighted bound, need names to be told apart)."""
        typ = g.str("type", choices=tuple(GOAL_TYPES))
        kw = {"hard": g.bool("hard")} if "hard" in g else {}
        name = g.str("name") if "name" in g else None
        if name is not None and not 0 < len(name.strip()) <= 80:
            raise g.error("name", expected="a goal name of 1 to 80 characters", got=name)
        goal = GOAL_TYPES[typ][1](g, kw)
        if name is not None:
            goal.label = name.strip()
        return goal

    def channels(self, Gp, dt) -> list[Channel]:
        raise NotImplementedError

    def detail(self, Gp, K) -> str:
        return ""


def _channel(Gp, opened, frm, to, **kw):
    P = cas.generalised_plant(Gp, opened, inputs=(frm,), outputs=(to,))
    return Channel(P, cas.N_MEAS, cas.N_CON, **kw)


@dataclasses.dataclass
class Tracking(Goal):
    frm: str = "theta_ref"
    to: str = "theta"
    response_time_s: float = 0.5
    dc_error: float = 1e-5
    peak_error: float = 1.0
    hard: bool = False
    band_rad_s: tuple = (0.0, np.inf)

    def __post_init__(self):
        if (self.frm, self.to) != ("theta_ref", "theta"):
            raise ConfigError("tracking is defined from 'theta_ref' to 'theta'", field="from/to",
                              got=f"{self.frm} -> {self.to}")
        self.label = f"tracking {self.frm}->{self.to} ({self.response_time_s} s)"

    def max_error(self):
        wc = 2.0 / self.response_time_s
        return ct.tf([self.peak_error, wc * self.dc_error], [1.0, wc])

    def channels(self, Gp, dt):
        return [_channel(Gp, (), "theta_ref", "e", weight=_inv(self.max_error()), hard=self.hard,
                         name=self.label, band_rad_s=tuple(self.band_rad_s))]


@dataclasses.dataclass
class CrossoverBand(Goal):
    loop: str = "theta"
    wc_min: float = 1.0
    wc_max: float = 10.0
    hard: bool = True

    def __post_init__(self):
        cas.check_point(self.loop)
        if not 0 < self.wc_min < self.wc_max:
            raise ConfigError("crossover band must satisfy 0 < wc_min < wc_max", field="band_rad_s",
                              got=[self.wc_min, self.wc_max])
        self.label = f"crossover {self.loop} in [{self.wc_min:g}, {self.wc_max:g}] rad/s"

    def _open(self, Gp):
        cut, inj, meas = cas.LOOP_POINTS[self.loop]
        return cas.generalised_plant(Gp, cut, inputs=(inj,), outputs=(meas,))

    def channels(self, Gp, dt):
        P = self._open(Gp)
        nyq = math.pi / dt if dt else 1e3 * self.wc_max
        return [Channel(P, cas.N_MEAS, cas.N_CON, mode="min", band_rad_s=(self.wc_min / 100, self.wc_min),
                        hard=self.hard, name=self.label + " (low)", npoints=150),
                Channel(P, cas.N_MEAS, cas.N_CON, mode="max", band_rad_s=(self.wc_max, nyq), hard=self.hard,
                        name=self.label + " (high)", npoints=150)]

    def loop_tf(self, Gp, K):
        return -closed_loop(self._open(Gp), cas.N_MEAS, cas.N_CON, K)

    def detail(self, Gp, K):
        wc = crossover_frequencies(self.loop_tf(Gp, K), w=_detail_grid(Gp))
        return "crossover " + (", ".join(f"{w:.2f}" for w in wc) if len(wc) else "none") + " rad/s"


@dataclasses.dataclass
class Sensitivity(Goal):
    point: str = "u"
    max_gain: object = 2.0
    hard: bool = False

    def __post_init__(self):
        cas.check_point(self.point)
        self.label = f"sensitivity at {self.point}"

    def channels(self, Gp, dt):
        frm, to = cas.SENSITIVITY[self.point]
        return [_channel(Gp, (), frm, to, weight=_inv(self.max_gain), hard=self.hard, name=self.label)]


@dataclasses.dataclass
class Rejection(Goal):
    frm: str = "d_u"
    to: str = "u"
    max_gain: object = 1.0
    hard: bool = False
    band_rad_s: tuple = (0.0, np.inf)

    def __post_init__(self):
        cas.check_signal(self.frm, "input")
        cas.check_signal(self.to, "output")
        self.label = f"rejection {self.frm}->{self.to}"

    def channels(self, Gp, dt):
        return [_channel(Gp, (), self.frm, self.to, weight=_inv(self.max_gain), hard=self.hard,
                         name=self.label, band_rad_s=tuple(self.band_rad_s))]


@dataclasses.dataclass
class Effort(Rejection):
    frm: str = "theta_ref"
    to: str = "u_ctrl"

    def __post_init__(self):
        super().__post_init__()
        self.label = f"effort {self.frm}->{self.to}"


@dataclasses.dataclass
class Margins(Goal):
    point: str = "u"
    gm_db: float = 6.0
    pm_deg: float = 45.0
    hard: bool = True

    def __post_init__(self):
        cas.check_point(self.point)
        self.label = f"margins at {self.point} (GM {self.gm_db:g} dB, PM {self.pm_deg:g} deg)"

    def alpha_req(self):
        g = 10 ** (self.gm_db / 20)
        return max(2 * (g - 1) / (g + 1), 2 * math.tan(math.radians(self.pm_deg) / 2))

    def channels(self, Gp, dt):
        frm, to = cas.SENSITIVITY[self.point]
        a = self.alpha_req()
        return [_channel(Gp, (), frm, to, offset=-0.5, weight=_Const(a), hard=self.hard,
                         name=self.label)]

    def detail(self, Gp, K):
        cut, inj, meas = cas.LOOP_POINTS[self.point]
        L = -closed_loop(cas.generalised_plant(Gp, cut, inputs=(inj,), outputs=(meas,)), cas.N_MEAS, cas.N_CON, K)
        m = margins(L, w=_detail_grid(Gp))
        return f"GM {m.gm_db:.1f} dB, PM {m.pm_deg:.1f} deg, disk alpha {m.disk_alpha:.2f}"


@dataclasses.dataclass
class Poles(Goal):
    min_damping: float = 0.0
    min_decay: float = 0.0
    hard: bool = True
    label: str = "poles"

    def channels(self, Gp, dt):
        return []

    def value(self, Gp, K):
        A = np.asarray(closed_loop(cas.generalised_plant(Gp), cas.N_MEAS, cas.N_CON, K).A, float)
        lam = np.linalg.eigvals(A)
        dt = float(Gp.dt) if lti.is_discrete(Gp) else 0.0
        if dt:
            lam = lam[np.abs(lam) > 1e-9]
            s = np.log(lam.astype(complex)) / dt
        else:
            s = lam
        decay = -s.real
        damp = decay / np.maximum(np.abs(s), 1e-300)
        v = 0.0
        if self.min_decay > 0:
            v = max(v, float(np.max(self.min_decay / np.maximum(decay, 1e-300))))
        if self.min_damping > 0:
            v = max(v, float(np.max(self.min_damping / np.maximum(damp, 1e-300))))
        if np.any(decay <= 0):
            v = np.inf
        return v, f"min damping {damp.min():.3f}, min decay {decay.min():.3f} 1/s"


def _weight(g: Table, key, default):
    """A maximum-gain profile: a positive number or a ``{kind = "highpass", order, gain_db, corner_rad_s}`` table."""
    w = g.raw(key, default)
    if _is_number(w):
        return g.num(key, default, lo=0.0, lo_open=True)
    if not isinstance(w, dict):
        raise g.error(key, expected='a positive number or a {kind = "highpass", ...} table', got=w)
    t = g.table(key)
    t.str("kind", choices=("highpass",))
    order = t.int("order", 1, lo=1, hi=8)
    gain_db = t.num("gain_db", lo=-200.0, hi=200.0)
    corner = t.num("corner_rad_s", lo=0.0, lo_open=True)
    return highpass_max_gain(order, gain_db, corner)


def _band(g: Table, key, default=REQUIRED):
    band = g.vec(key, 2, default, lo=0.0, allow_inf=True)
    if band[0] >= band[1] or math.isinf(band[0]):
        raise g.error(key, expected="[low, high] in rad/s with low < high", got=list(band))
    return band


def _crossover(g: Table, kw):
    lo, hi = _band(g, "band_rad_s")
    return CrossoverBand(g.str("loop"), lo, hi, **kw)


def _tracking(g: Table, kw):
    return Tracking(g.str("from", "theta_ref"), g.str("to", "theta"), g.num("response_time_s", lo=0.0, lo_open=True),
                    g.num("max_error_pct", 0.001, lo=0.0, lo_open=True, hi=100.0) / 100.0,
                    g.num("peak_error", 1.0, lo=0.0, lo_open=True),
                    band_rad_s=_band(g, "band_rad_s", (0.0, math.inf)), **kw)


def _rejection(g: Table, kw):
    return Rejection(g.str("from"), g.str("to"), _weight(g, "weight", 1.0),
                     band_rad_s=_band(g, "band_rad_s", (0.0, math.inf)), **kw)


def _sensitivity(g: Table, kw):
    return Sensitivity(g.str("point"), _weight(g, "weight", 2.0), **kw)


def _effort(g: Table, kw):
    return Effort(frm=g.str("from", "theta_ref"), to=g.str("to", "u_ctrl"), max_gain=_weight(g, "max_gain", 1.0), **kw)


def _margins(g: Table, kw):
    return Margins(g.str("point", "u"), g.num("gm_db", 6.0, lo=0.0, hi=100.0), g.num("pm_deg", 45.0, lo=0.0, hi=180.0),
                   **kw)


def _poles(g: Table, kw):
    return Poles(g.num("min_damping", 0.0, lo=0.0, hi=1.0), g.num("min_decay", 0.0, lo=0.0), **kw)


#: TOML ``type`` -> (goal class, reader of its keys from a strict Table): the registry :meth:`Goal.from_toml`
#: dispatches on. A new goal type is one class plus one entry here.
GOAL_TYPES = {
    "crossover": (CrossoverBand, _crossover),
    "tracking": (Tracking, _tracking),
    "rejection": (Rejection, _rejection),
    "gain": (Rejection, _rejection),
    "sensitivity": (Sensitivity, _sensitivity),
    "effort": (Effort, _effort),
    "margins": (Margins, _margins),
    "poles": (Poles, _poles),
}


@dataclasses.dataclass
class GoalResult:
    goal: str
    model: str
    value: float
    bound: float
    passed: bool
    hard: bool
    detail: str = ""


def _models_plants(models, dt):
    return [(m, cas.cascade_plant(m, dt)) for m in models]


def evaluate(spec, gains, models) -> list[GoalResult]:
    """Every goal of ``spec`` on every model for the gain set ``gains`` (GainSet or AxisGains).

    Parameters
    ----------
    spec : Spec
        The goals and the cascade settings (:func:`rotorlab.tune.load_spec`).
    gains : GainSet or AxisGains
        The gains to score (the spec's axis is taken from a GainSet).
    models : sequence of PlantModel
        Plant models; every goal is evaluated on each.

    Returns
    -------
    list of GoalResult
        One per goal and model: value (<= 1 meets the goal), bound, pass/fail, hard or soft, detail.

    Examples
    --------
    >>> from rotorlab import tune
    >>> from rotorlab.gains import load_gains
    >>> from rotorlab.vehicles import gains_path
    >>> plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06, name="test-bed")
    >>> spec = tune.load_spec("anteos-p2a2")
    >>> standard = load_gains(gains_path("anteos-p2a2", "standard"))

    >>> results = tune.evaluate(spec, standard, [plant])
    >>> [r.goal for r in results if r.hard and not r.passed][:2]   # the standard gains miss the crossover band
    ['crossover q in [3.5, 14] rad/s', 'tracking theta_ref->theta (0.5 s)']
    """
    ax = gains[spec.axis] if isinstance(gains, GainSet) else gains
    S = cas.cascade_structure(spec.dt, ax)
    th = cas.gains_to_theta(S, ax)
    K = S.ss(th)
    out = []
    for m, Gp in _models_plants(models, spec.dt):
        stable = lti.is_stable(closed_loop(cas.generalised_plant(Gp), cas.N_MEAS, cas.N_CON, K))
        # every goal's channels in one problem: their peaks come from one batched evaluation
        per_goal = [(g, g.channels(Gp, spec.dt)) for g in spec.goals if not isinstance(g, Poles)]
        chans = [c for _, cs in per_goal for c in cs]
        peaks = {}
        if stable and chans:
            allp = _Problem(S, chans, [], np.zeros(len(th), bool), np.ones(0)).all_peaks(th, nmax=3)
            i = 0
            for g, cs in per_goal:
                peaks[id(g)] = allp[i:i + len(cs)]
                i += len(cs)
        for g in spec.goals:
            if isinstance(g, Poles):
                v, det = g.value(Gp, K)
            elif not stable:
                v, det = np.inf, "closed loop unstable"
            else:
                v = max((p[0][0] for p in peaks[id(g)]), default=0.0)
                det = g.detail(Gp, K)
            out.append(GoalResult(g.label, m.name, float(v), 1.0, bool(v <= 1.0), g.hard, det))
    return out


def objective(results: list[GoalResult]) -> float:
    """Weighted objective systune minimises: the largest normalised soft-goal value (hard goals if none)."""
    soft = [r.value for r in results if not r.hard]
    return max(soft) if soft else max(r.value for r in results)


@dataclasses.dataclass
class TuneResult:
    gains: object
    report: list
    objective: float
    history: list
    starts: list
    time_s: float


def tune_cascade(spec, models, start_gains, *, starts: int = 1, seed=0, n_jobs: int = 1, tol: float = 1e-3,
                 max_iter: int = 40, time_limit_s=None, name: str = "tuned", progress: bool = False,
                 executor=None) -> TuneResult:
    """Tune the parameters listed in ``spec.tune`` against ``spec.goals`` on every model.

    Each start runs the structured H-inf engine of :mod:`rotorlab.tune.hinfstruct` (stabilisation phase, then
    tangent-program steps with hard goals as constraints and the stationarity stop, alternated with BFGS on
    the exact penalty); ``max_iter`` bounds both kinds of iteration together.

    The starts run through ``executor`` (a :class:`rotorlab.executor.Executor`, e.g. the pipeline's, local or
    Dask) or, without one, a local pool of ``n_jobs`` processes (:func:`rotorlab.tune.hinfstruct.run_starts`); the
    result does not depend on where they ran.

    Parameters
    ----------
    spec : Spec
        Goals, cascade settings and the parameters to tune (``spec.tune``).
    models : sequence of PlantModel
        The goals hold on every model (multi-model tuning).
    start_gains : GainSet or AxisGains
        The first start; further starts are random perturbations of it (``seed``).
    starts : int
        Number of starts; the best feasible result is returned.
    seed : int
        Root seed of the starts.
    n_jobs : int
        Local worker processes when no ``executor`` is given.
    tol, max_iter, time_limit_s
        Stopping rules of each start.
    name : str
        Name of the returned gain set.
    progress : bool
        Show a progress bar.
    executor : rotorlab.executor.Executor, optional
        Runs the starts.

    Returns
    -------
    TuneResult
        ``gains`` (a GainSet), ``report`` (GoalResults of the best start), ``objective`` (the worst soft goal),
        ``history``, ``starts`` (one record per start) and ``time_s``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> from rotorlab.gains import load_gains
    >>> from rotorlab.vehicles import gains_path
    >>> plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06, name="test-bed")
    >>> spec = tune.load_spec("anteos-p2a2")
    >>> standard = load_gains(gains_path("anteos-p2a2", "standard"))

    >>> res = tune.tune_cascade(spec, [plant], standard, starts=1, seed=0)
    >>> all(r.passed for r in res.report if r.hard), bool(res.objective < 1.0)
    (True, True)
    """
    t0 = time.perf_counter()
    ax = start_gains[spec.axis] if isinstance(start_gains, GainSet) else start_gains
    S = cas.cascade_structure(spec.dt, ax)
    th0 = cas.gains_to_theta(S, ax)
    names = S.names
    free = np.array([n in spec.tune and not S.params[i].fixed for i, n in enumerate(names)])
    lower = np.array([p.lower for p in S.params])
    upper = np.array([p.upper for p in S.params])
    for i, n in enumerate(names):  # PID gains keep their sign (all published gains are positive)
        if n.split(".")[1] in ("kp", "ki", "kd"):
            lower[i] = max(lower[i], 0.0)
    channels, stab = [], []
    poles = None
    for _m, Gp in _models_plants(models, spec.dt):
        stab.append((cas.generalised_plant(Gp), cas.N_MEAS, cas.N_CON))
        for g in spec.goals:
            channels += g.channels(Gp, spec.dt)
            if isinstance(g, Poles):
                poles = (g.min_decay, g.min_damping)
    scale = np.maximum(np.abs(th0[free]), 1e-3)
    prob = _Problem(S, channels, stab, free, scale, poles=poles)
    results = run_starts(prob, th0, lower, upper, starts=starts, seed=seed, n_jobs=n_jobs, max_iter=max_iter,
                         tol=tol, time_limit_s=time_limit_s, spread=0.3, progress=progress, executor=executor,
                         sub_iter=SPEC_SUB_ITER, sampling=False)
    best, best_key, per_start = None, None, []
    for r in results:
        if isinstance(r, StartFailure):
            per_start.append(np.inf)
            continue
        th, merit, hist = r[:3]
        per_start.append(float(merit[1]) if merit[0] <= 1e-9 else np.inf)
        key = (merit[0] > 1e-9, merit[0], merit[1])
        if best_key is None or key < best_key:
            best, best_key = r, key
    if best is None:
        raise ValueError("no start stabilises the cascade on every model; start from gains that do")
    th, _, hist = best[:3]
    gs = cas.theta_to_gains(S, th, name=name, axis=spec.axis)
    rep = evaluate(spec, gs, models)
    return TuneResult(gs, rep, objective(rep), list(map(float, hist)), per_start, time.perf_counter() - t0)


def format_report(results: list[GoalResult]) -> str:
    """The goal results as a plain-text table (what ``rotorlab tune`` prints).

    Parameters
    ----------
    results : list of GoalResult
        From :func:`evaluate` or ``TuneResult.report``.

    Returns
    -------
    str
        A fixed-width table, one line per goal and model, with PASS/FAIL and whether the goal is hard.

    Examples
    --------
    >>> from rotorlab import tune
    >>> from rotorlab.gains import load_gains
    >>> from rotorlab.vehicles import gains_path
    >>> plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06, name="test-bed")
    >>> spec = tune.load_spec("anteos-p2a2")
    >>> standard = load_gains(gains_path("anteos-p2a2", "standard"))

    >>> print(tune.format_report(tune.evaluate(spec, standard, [plant])).splitlines()[0])
    goal                                             model            value  bound        detail
    """
    lines = [f"{'goal':<48} {'model':<12} {'value':>9} {'bound':>6}  {'':4}  detail"]
    for r in results:
        kind = "hard" if r.hard else "soft"
        lines.append(f"{r.goal[:48]:<48} {r.model[:12]:<12} {r.value:9.4f} {r.bound:6.2f}  "
                     f"{'PASS' if r.passed else 'FAIL'}  ({kind}) {r.detail}")
    return "\n".join(lines)
