"""Per-axis identification from a flight log: the plant (rate-loop output -> rate), the closed loop (rate
set-point -> rate), and the plant recovered through the known controller (indirect route).

The direct fits use the project's methods (:data:`rotorlab.ident.methods.METHODS`): a few orders and methods
are fitted on the identification windows and the one that predicts the identification data best is kept (never
the held-out data, which only scores the result). The indirect fit takes the controller as a
python-control LTI system, so the autopilot's law (``rotorlab.autopilots``) plugs in from outside:
``identify_plant_indirect(record, split, controller_lti)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import control as ct
import numpy as np

from rotorlab.errors import DataError
from rotorlab.lti import as_ss, is_discrete

from ..delay import estimate_delay
from ..greybox import GreyBoxModel, _closed_loop, lift_interpolated, oe_fit_closed_loop, simulate_closed_loop
from ..methods import METHODS
from ..metrics import simulate, vaf
from ..model import IdentifiedModel
from .flightlog import Record
from .plant_structures import plant_structure, rate_angle_plant_structure, rate_plant_structure
from .windows import Split

__all__ = ["AxisModel", "CANDIDATES", "FALLBACK", "MAX_FIT_SAMPLES", "identify_direct", "identify_plant_indirect", "rate_plant_structure",
           "controller_at", "loop_substeps", "holdout_prediction", "window_runs", "rate_angle_plant_structure",
           "angle_cascade", "identify_plant_through_angle_loop"]

# (method, settings) tried by the direct fits, per kind. Orders 2-4 cover a rate loop (integrator, motor lag,
# filters). The plant is seen in closed loop, where only PBSID (predictor-based) is consistent: past-input
# instruments and ARX are biased by the noise the feedback returns to the input. ARX stays for the closed loop,
# where it is the baseline.
CANDIDATES = {
    "closed-loop": (
        ("pi-moesp", {"order": 2, "horizon": 20}),
        ("pi-moesp", {"order": 3, "horizon": 20}),
        ("pi-moesp", {"order": 4, "horizon": 20}),
        ("pbsid", {"order": 2, "past": 20, "future": 10}),
        ("pbsid", {"order": 4, "past": 20, "future": 10}),
        ("arx", {"order": 2}),
        ("arx", {"order": 4}),
    ),
    "plant": (
        ("pbsid", {"order": 2, "past": 40, "future": 20}),
        ("pbsid", {"order": 3, "past": 40, "future": 20}),
        ("pbsid", {"order": 4, "past": 40, "future": 20}),
    ),
}
# the closed loop from the attitude set-point (an angle mode's input) takes the closed loop's candidates
CANDIDATES["closed-loop-angle"] = CANDIDATES["closed-loop"]
# tried when no candidate of CANDIDATES fits (windows too short for PBSID's 40-sample past)
FALLBACK = {
    "closed-loop": (),
    "closed-loop-angle": (),
    "plant": (
        ("pbsid", {"order": 2, "past": 20, "future": 10}),
        ("pbsid", {"order": 4, "past": 20, "future": 10}),
    ),
}
MIN_SAMPLES = 100
# Samples a candidate is fitted on (and scored on, and twice this for the refit): 20 s at 250 Hz is hundreds of
# rate-loop time constants, and the cost of the fits grows with the data while the model stops improving; a long
# log's further windows add time, not information (the held-out score always uses every held-out window)
MAX_FIT_SAMPLES = 5000
# a closed rate loop is stable; a plant may integrate (rate from torque), so one pole may sit on the unit circle
MAX_POLE_RADIUS = {"closed-loop": 1.0 - 1e-9, "closed-loop-angle": 1.0 - 1e-9, "plant": 1.0 + 1e-4}
KINDS = {"closed-loop": ("rate_sp", "rate"), "closed-loop-angle": ("att_sp", "rate"), "plant": ("rate_out", "rate")}


@dataclass
class AxisModel:
    """One identified model of one axis, with how it was chosen and how it predicts the held-out data.

    Attributes
    ----------
    axis : str
    kind : {"closed-loop", "plant", "plant-indirect", "closed-loop-indirect"}
    model : IdentifiedModel
        Discrete at ``dt`` (delay in samples); for ``plant-indirect`` the discretised grey-box plant.
    input, output : str
    units : dict
    dt : float
    split : Split
    vaf_holdout : float
        Free-run VAF (%) on the held-out windows (initial state fitted per window, as
        :func:`rotorlab.ident.metrics.simulate`).
    tried : list of (str, float)
        Candidates and their VAF on the identification data they were not fitted on.
    prediction : list of (t_s, y, y_hat)
        Per held-out window, for the report.
    extra : dict
        Grey-box parameters and the like.
    """

    axis: str
    kind: str
    model: IdentifiedModel
    input: str
    output: str
    units: dict
    dt: float
    split: Split
    vaf_holdout: float = float("nan")
    tried: list = field(default_factory=list)
    prediction: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)


def window_runs(rec: Record, windows, min_samples: int = 50) -> list[np.ndarray]:
    """Sample indices of each window (those shorter than ``min_samples`` dropped)."""
    out = []
    for w in windows:
        idx = np.flatnonzero((rec.t_s >= w.start_s) & (rec.t_s < w.stop_s))
        if len(idx) >= min_samples:
            out.append(idx)
    return out


def _capped(runs, n: int) -> list:
    """The first runs (whole, the last one cut) holding at most ``n`` samples together; runs under
    ``MIN_SAMPLES`` left after the cut are dropped."""
    out, left = [], n
    for r in runs:
        if left < MIN_SAMPLES:
            break
        out.append(r[:left])
        left -= len(out[-1])
    return out


def _centred(x, idx):
    """``x[idx]`` with its mean removed: trims (a set-point offset, the torque that balances an off-centre mass,
    a gyro bias) are constants outside the LTI model, so every window is fitted and predicted about its mean."""
    v = x[idx]
    return v - v.mean()


def _predict(model, u, y, r) -> np.ndarray:
    return simulate(model, _centred(u, r), x0="estimate", y=_centred(y, r)).ravel() + y[r].mean()


def _pooled_vaf(model, u, y, runs) -> float:
    ys, yh = [], []
    for r in runs:
        ys.append(y[r])
        yh.append(_predict(model, u, y, r))
    pred = np.concatenate(yh)
    if not np.all(np.isfinite(pred)):
        return 0.0
    return float(vaf(np.concatenate(ys), pred)[0])


def holdout_prediction(model, rec: Record, u_name: str, y_name: str, windows) -> tuple[float, list]:
    """(pooled free-run VAF %, [(t_s, y, y_hat)] per window) of ``model`` on ``windows`` of ``rec``."""
    runs = window_runs(rec, windows)
    if not runs:
        raise DataError(f"the {rec.axis} axis has no held-out window of at least 50 samples")
    u, y = rec.data[u_name], rec.data[y_name]
    pred = [(rec.t_s[r], y[r], _predict(model, u, y, r)) for r in runs]
    yh = np.concatenate([p[2] for p in pred])
    v = float(vaf(np.concatenate([p[1] for p in pred]), yh)[0]) if np.all(np.isfinite(yh)) else 0.0
    return v, pred


def _fit(name, u, y, dt, delay, settings):
    return METHODS[name].fit(u, y, dt=dt, delay=delay, **settings)


def _delay(u, y, max_delay: int = 10) -> int | None:
    try:
        return estimate_delay(u, y, max_delay)
    except DataError:
        return None  # no significant lag found


def _radius(m) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(np.asarray(m.sys.A, float))), initial=0.0))


def _refit_scored(name, settings, d, joined, m, inner_vaf, label, kind, rec, u, y, runs):
    """(model, score, label) of a closed-loop candidate: refitted on every identification window joined, scored
    by the refit's free-run VAF on them; the fit on 75 % of the longest window where the refit leaves the unit
    circle.

    The model delivered is the one scored. On a pilot's log a candidate's fit on part of one window and its
    refit on the whole flight can differ by tens of points (a set-point fed back from the measured attitude in
    heading hold makes the few-parameter fits lean on which stretch they see), so ranking the part's fit chose
    models whose refit did not reproduce even the data it was fitted on. The fits minimise an equation or
    projection error, not the free-run error, and have at most a few tens of parameters against hundreds of
    samples, so the free-run VAF on the fitted data ranks them without rewarding the larger order."""
    M = _fit(name, *joined, rec.dt, d, settings)
    if _radius(M) > MAX_POLE_RADIUS[kind]:
        return m, _pooled_vaf(m, u, y, runs), f"{label} (refit unstable; the 75 % fit, VAF on the rest {inner_vaf:.1f})"
    return M, _pooled_vaf(M, u, y, runs), f"{label} (the 75 % fit's VAF on the rest {inner_vaf:.1f})"


def identify_direct(rec: Record, split: Split, kind: str = "closed-loop", candidates=None) -> AxisModel:
    """Identify ``kind`` (closed-loop: rate_sp -> rate; plant: rate_out -> rate) of one axis.

    Every candidate of ``candidates`` (default ``CANDIDATES[kind]``, then ``FALLBACK[kind]`` if none fits), at
    the estimated input delay (the closed loop also at the two delays below it and none), is fitted on the first
    75 % of the longest identification window and scored on the rest
    of the identification windows; candidates with a pole outside the unit circle (on it for a plant, which
    may integrate) are dropped; the best is refitted on all identification windows joined (each about its mean)
    and scored on the held-out windows. A closed loop's candidates are each refitted on all identification
    windows and ranked by that refit's free-run VAF on them (the model delivered is the one ranked), the score on
    the rest kept in ``tried``'s labels.

    Raises
    ------
    DataError
        No identification window long enough, or no candidate gives a finite model.

    Examples
    --------
    >>> res = identify_direct(rec, split, "closed-loop")  # doctest: +SKIP
    >>> res.vaf_holdout  # doctest: +SKIP
    """
    u_name, y_name = KINDS[kind]
    u, y = rec.data[u_name], rec.data[y_name]
    runs = window_runs(rec, split.ident, MIN_SAMPLES)
    if not runs:
        raise DataError(f"the {rec.axis} axis has no identification window of at least {MIN_SAMPLES} samples "
                        f"({MIN_SAMPLES * rec.dt:.3g} s at {1 / rec.dt:.4g} Hz)")
    runs.sort(key=len, reverse=True)
    main = runs[0]
    k = min(int(0.75 * len(main)), MAX_FIT_SAMPLES)
    fit_idx, inner = main[:k], _capped([main[k:]] + runs[1:], MAX_FIT_SAMPLES)
    runs = _capped(runs, 2 * MAX_FIT_SAMPLES)
    uf, yf = _centred(u, fit_idx), _centred(y, fit_idx)
    delay = _delay(uf, yf)
    tried, best = [], None
    sets = [candidates] if candidates is not None else [CANDIDATES[kind], FALLBACK[kind]]
    # the closed loop also at the two delays below the estimate and none: a slow axis (yaw) pushes the first
    # significant lag late, and a loop logged slower than it runs answers within a sample. The plant keeps the
    # estimate: its first Markov parameter is what estimate_delay reads, and a shorter delay lets a low order
    # trade dynamics for it
    if kind.startswith("closed-loop"):
        d = 2 if delay is None else delay
        delays = sorted({d, max(d - 1, 0), max(d - 2, 0), 0}, reverse=True)
    else:
        delays = [delay or 0]
    joined = (np.concatenate([_centred(u, r) for r in runs]), np.concatenate([_centred(y, r) for r in runs]))
    for name, settings in (c for cs in sets for c in cs):
        if best is not None and candidates is None and (name, settings) in FALLBACK[kind]:
            break
        for d in delays:
            label = f"{name} " + " ".join(f"{a}={b}" for a, b in settings.items()) + f" delay={d}"
            try:
                m = _fit(name, uf, yf, rec.dt, d, settings)
                radius = _radius(m)
                if radius > MAX_POLE_RADIUS[kind]:
                    tried.append((f"{label}: pole radius {radius:.4f} (unstable {kind} model)", float("nan")))
                    continue
                score = _pooled_vaf(m, u, y, inner)
                final = m
                if kind.startswith("closed-loop"):
                    final, score, label = _refit_scored(name, settings, d, joined, m, score, label, kind, rec, u, y,
                                                        runs)
            except (DataError, ValueError, np.linalg.LinAlgError) as exc:
                tried.append((f"{label}: {exc}", float("nan")))
                continue
            tried.append((label, score))
            if best is None or score > best[2]:
                best = (name, settings, score, d, final)
    if best is None:
        raise DataError(f"no {kind} model of the {rec.axis} axis could be fitted: "
                        + "; ".join(t for t, _ in tried))
    delay = best[3]
    if kind.startswith("closed-loop"):
        model = best[4]
    else:
        # the refit takes every identification window, each about its own mean, joined end to end: the seams
        # cost a few samples of misfit, the extra data (pilot inputs come in bursts) is worth more
        model = _fit(best[0], *joined, rec.dt, delay, best[1])
        if _radius(model) > MAX_POLE_RADIUS[kind]:
            # the refit crossed the unit circle: keep the candidate fit that passed the check
            model = best[4]
    v, pred = holdout_prediction(model, rec, u_name, y_name, split.holdout)
    return AxisModel(rec.axis, kind, model, u_name, y_name, {u_name: rec.units[u_name], y_name: rec.units[y_name]},
                     rec.dt, split, v, tried, pred)


def _d2c_tustin(sysd: ct.StateSpace) -> ct.StateSpace:
    """The continuous system whose Tustin discretisation at ``sysd.dt`` is ``sysd`` (exact inverse).

    A controller's difference states have poles at ``z = 0``, which the ZOH inverse (a matrix logarithm) cannot
    map; the bilinear map can (to ``s = -2/dt``), so a round trip through it at another rate keeps the response.
    Needs no pole at ``z = -1``.
    """
    A, B, C, D = (np.asarray(M, float) for M in (sysd.A, sysd.B, sysd.C, sysd.D))
    T = float(sysd.dt)
    if A.shape[0] == 0:
        return ct.ss([], [], [], D)
    M = np.linalg.inv(A + np.eye(A.shape[0]))
    return ct.ss((2.0 / T) * (A - np.eye(A.shape[0])) @ M, (2.0 / T) * M @ B, 2.0 * C @ M, D - C @ M @ B)


def loop_substeps(controller, dt: float) -> int:
    """Loop ticks per log sample: ``round(dt / controller.dt)`` for a discrete controller whose loop runs at least
    1.5 times faster than the log is sampled, else 1.

    At the log's rate a 400 Hz law with 20 Hz filters, moved to a 25 Hz log (Nyquist 12.5 Hz), is no longer the
    law that flew; simulated at its own rate between the log's samples it is.

    Examples
    --------
    >>> loop_substeps(ct.ss([], [], [], [[1.0]], 1 / 400), 1 / 24)
    17
    >>> loop_substeps(ct.ss([], [], [], [[1.0]], 1 / 400), 1 / 300)
    1
    """
    K = as_ss(controller)
    if not is_discrete(K) or K.dt is True or float(K.dt) * 1.5 > dt:
        return 1
    return max(1, int(round(dt / float(K.dt))))


def controller_at(controller, dt: float) -> ct.StateSpace:
    """The controller as a discrete system at ``dt``: as is when its sample time is ``dt``; a continuous one by
    Tustin; a discrete one at another rate (the autopilot's loop rate above the log's) through the continuous
    system whose Tustin form it is, then Tustin at ``dt``.

    Examples
    --------
    >>> C = controller_at(ct.c2d(ct.tf([0.1, 1.0], [1.0, 0.0]), 0.001, "tustin"), 0.004)
    >>> float(C.dt)
    0.004
    """
    K = as_ss(controller)
    if is_discrete(K):
        if abs(float(K.dt) - dt) <= 1e-9 * dt:
            return K
        K = _d2c_tustin(K)
    return ct.c2d(K, dt, method="tustin")


def identify_plant_indirect(rec: Record, split: Split, controller_lti, structure: GreyBoxModel | None = None,
                            *, rng=None) -> AxisModel:
    """The plant recovered from closed-loop data through the known controller (indirect route).

    The loop ``rate_out = C [rate_sp; rate]`` (a two-input controller: set-point and measured rate, the PX4
    and ArduPilot form with derivative on the measurement and feed-forward) or ``rate_out = C (rate_sp - rate)``
    (one input) is simulated with the plant ``structure`` (default: the axis's,
    :func:`rotorlab.ident.flightlogs.plant_structures.plant_structure`) and the plant
    parameters fitted to the measured rate (``oe_fit_closed_loop``, initial state estimated) on the longest
    identification window. A log written at least 1.5 times slower than a discrete controller's loop is
    simulated at the loop rate between its samples (:func:`loop_substeps` steps per sample, the set-point
    interpolated linearly, the rate compared at the log's samples:
    :func:`rotorlab.ident.greybox.lift_interpolated`); otherwise the controller is moved to the log's rate
    (:func:`controller_at`). The fitted plant is closed again with the controller the same way and scored on
    the held-out windows; ``model`` is the discretised plant.

    Parameters
    ----------
    rec : Record
        With ``rate_sp`` and ``rate``.
    split : Split
    controller_lti : control.StateSpace or TransferFunction
        The rate controller (``rotorlab.autopilots`` builds it from the log's parameters), continuous or
        discrete at any rate (see :func:`controller_at`).
    structure : GreyBoxModel, optional

    Examples
    --------
    >>> res = identify_plant_indirect(rec, split, controller_lti)  # doctest: +SKIP
    >>> res.extra["params"]  # doctest: +SKIP
    """
    structure = structure or plant_structure(rec.axis)
    sub = loop_substeps(controller_lti, rec.dt)
    K = controller_at(controller_lti, rec.dt / sub)
    runs = window_runs(rec, split.ident, MIN_SAMPLES)
    if not runs:
        raise DataError(f"the {rec.axis} axis has no identification window of at least {MIN_SAMPLES} samples")
    main = max(runs, key=len)[:MAX_FIT_SAMPLES]
    r, y = rec.data["rate_sp"][main], rec.data["rate"][main]
    r, y = r - r.mean(), y - y.mean()
    # a coarse scan of the gain first: the closed-loop cost is far from convex in K (too high a gain makes the
    # simulated loop unstable, a plateau for the optimiser); the scan simulates, it does not fit
    theta0 = None
    if "K" in structure.free:
        grid = structure.param("K").value * np.logspace(-2, 2, 17)
        costs = []
        for kk in grid:
            ys = simulate_closed_loop(structure, K, r, rec.dt, {**structure.values(), "K": float(kk)}, substeps=sub)
            with np.errstate(over="ignore", invalid="ignore"):  # a gain that destabilises the loop diverges
                e = y - (ys[:, 0] - ys[:, 0].mean())
                cost = float(np.mean(e * e))
            costs.append(cost if np.isfinite(cost) else np.inf)
        theta0 = {"K": float(grid[int(np.argmin(costs))])}
    res = oe_fit_closed_loop(structure, K, r, y, rec.dt, theta0, estimate_x0=True, cov="white", rng=rng,
                             substeps=sub)
    plant_d = res.discrete()
    plant_f = res.model.discretize(rec.dt / sub)
    cl = IdentifiedModel(sys=lift_interpolated(_closed_loop(plant_f, K, 0), sub),
                         method="closed-loop-through-controller", settings={"substeps": sub})
    v, pred = holdout_prediction(cl, rec, "rate_sp", "rate", split.holdout)
    return AxisModel(rec.axis, "plant-indirect", plant_d, "rate_out", "rate", {"rate_out": "1", "rate": "rad/s"},
                     rec.dt, split, v, [], pred, {"params": dict(res.params), "ci95": dict(res.ci95),
                                                  "closed_loop": cl, "fit_vaf": float(np.ravel(res.fit_vaf)[0]),
                                                  "substeps": sub})


def angle_cascade(rate_controller, angle_p: float, ff: float, dt: float) -> ct.StateSpace:
    """The angle and rate controllers as one system ``[att_sp, rate, att] -> rate_out`` at ``dt``: ``rate_sp =
    angle_p (att_sp - att) + ff (att_sp[k] - att_sp[k-1]) / dt`` (the angle P and the attitude set-point's rate
    as feed-forward, ArduPilot's and PX4's linear angle law) into the two-input rate controller ``[rate_sp, rate]``
    (moved to ``dt`` by :func:`controller_at`).

    Examples
    --------
    >>> K = angle_cascade(ct.ss([], [], [], [[0.1, -0.1]], 0.0025), 6.0, 0.0, 0.0025)
    >>> np.round(np.asarray(K.D), 3).tolist()
    [[0.6, -0.1, -0.6]]
    """
    C2 = controller_at(rate_controller, dt)
    if C2.ninputs != 2:
        raise ValueError(f"the rate controller must take [rate_sp, rate]; it has {C2.ninputs} inputs")
    k = ff / dt
    pre = ct.ss([[0.0]], [[1.0, 0.0, 0.0]], [[-k], [0.0]], [[angle_p + k, 0.0, -angle_p], [0.0, 1.0, 0.0]], dt)
    return ct.series(pre, C2)


def identify_plant_through_angle_loop(rec: Record, split: Split, rate_controller, angle_p: float, ff: float = 0.0,
                                      structure: GreyBoxModel | None = None, *, rng=None) -> AxisModel:
    """The plant recovered through the angle and rate controllers from the attitude set-point (indirect route of
    an angle mode, where the logged rate set-point is the angle loop's output and not an input).

    As :func:`identify_plant_indirect`, with the loop ``rate_out = angle_cascade(...) [att_sp; rate; att]``
    closed around ``structure`` (default :func:`rate_angle_plant_structure`) and fitted to the measured rate and
    attitude on the longest identification window (``oe_fit_closed_loop``, initial state estimated); the fitted
    plant closed again the same way is scored on the held-out rate from the attitude set-point.

    Parameters
    ----------
    rec : Record
        With ``att_sp``, ``rate``, ``att``; the angles continuous (unwrapped) and in one branch.
    split : Split
    rate_controller : control LTI
        Two inputs ``[rate_sp, rate]``.
    angle_p : float
        The angle P, 1/s.
    ff : float
        The attitude set-point's rate fed forward into the rate set-point (1: ArduCopter with ATC_RATE_FF_ENAB).

    Examples
    --------
    >>> res = identify_plant_through_angle_loop(rec, split, C, angle_p=8.3, ff=1.0)  # doctest: +SKIP
    >>> res.extra["params"]["K"]  # doctest: +SKIP
    """
    structure = structure or rate_angle_plant_structure()
    sub = loop_substeps(rate_controller, rec.dt)
    K = angle_cascade(rate_controller, angle_p, ff, rec.dt / sub)
    runs = window_runs(rec, split.ident, MIN_SAMPLES)
    if not runs:
        raise DataError(f"the {rec.axis} axis has no identification window of at least {MIN_SAMPLES} samples")
    main = max(runs, key=len)[:MAX_FIT_SAMPLES]
    r = _centred(rec.data["att_sp"], main)
    y = np.column_stack([_centred(rec.data["rate"], main), _centred(rec.data["att"], main)])
    # the coarse gain scan of identify_plant_indirect, on the rate
    grid = structure.param("K").value * np.logspace(-2, 2, 17)
    costs = []
    for kk in grid:
        with np.errstate(over="ignore", invalid="ignore"):  # a gain that destabilises the loop diverges
            ys = simulate_closed_loop(structure, K, r, rec.dt, {**structure.values(), "K": float(kk)},
                                      feedback_output=(0, 1), substeps=sub)
            e = y[:, 0] - (ys[:, 0] - ys[:, 0].mean())
            cost = float(np.mean(e * e))
        costs.append(cost if np.isfinite(cost) else np.inf)
    theta0 = {"K": float(grid[int(np.argmin(costs))])}
    res = oe_fit_closed_loop(structure, K, r, y, rec.dt, theta0, feedback_output=(0, 1), estimate_x0=True,
                             cov="white", rng=rng, substeps=sub)
    plant_f = res.model.discretize(rec.dt / sub)
    cl = IdentifiedModel(sys=lift_interpolated(_closed_loop(plant_f, K, (0, 1)), sub)[0, :],
                         method="closed-loop-through-angle-and-rate-controller", settings={"substeps": sub})
    v, pred = holdout_prediction(cl, rec, "att_sp", "rate", split.holdout)
    plant_d = res.discrete()
    # the rate plant: the attitude state, unseen from the rate, goes
    plant_rate = replace(plant_d, sys=ct.minreal(plant_d.sys[0, :], verbose=False))
    return AxisModel(rec.axis, "plant-indirect-angle", plant_rate, "rate_out", "rate",
                     {"rate_out": "1", "rate": "rad/s"}, rec.dt, split, v, [], pred,
                     {"params": dict(res.params), "ci95": dict(res.ci95), "closed_loop": cl, "angle_p": angle_p,
                      "ff": ff,
                      "fit_vaf": [float(x) for x in np.ravel(res.fit_vaf)], "substeps": sub})
