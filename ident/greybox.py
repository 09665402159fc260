"""Grey-box identification: continuous-time models with named, bounded physical parameters, fitted by
output-error maximum likelihood, open loop or in closed loop with a known controller.

The model is simulated exactly at the data's sample time (zero-order hold with the transport delay,
fractional part included, :func:`rotorlab.lti.c2d_zoh_delay`), so the delay is a continuous parameter
like any other. With Gaussian white measurement noise the ML estimate is the least-squares fit of the
simulated output (Riccardi et al., doc 000 "Output Error Maximum Likelihood"), solved here with
``scipy.optimize.least_squares`` (trust-region reflective, bounds) instead of the papers' Newton-Raphson.
The parameter covariance is ``sigma^2 (J^T J)^-1`` at the optimum, with ``sigma^2`` the residual
variance; confidence intervals use Student's t.

Unknown initial states are estimated by variable projection (Golub & Pereyra): for each parameter value
the initial state enters linearly and is solved by linear least squares, so it never enlarges the
nonlinear search and unobservable directions (e.g. the common-mode angle of the pitch structure) are
harmless.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import control as ct
import numpy as np
import scipy.optimize as opt
import scipy.signal as sig
import scipy.stats as st
from tqdm.auto import tqdm

from rotorlab.ident._data import as_columns
from rotorlab.ident.metrics import vaf
from rotorlab.ident.model import IdentifiedModel
from rotorlab.lti import as_ss, c2d_zoh_delay, is_discrete

__all__ = [
    "Param",
    "GreyBoxModel",
    "GreyBoxResult",
    "oe_fit",
    "lift_interpolated",
    "oe_fit_closed_loop",
    "periodic_average",
    "simulate_greybox",
    "simulate_closed_loop",
    "split_periods",
]


@dataclass(frozen=True)
class Param:
    """One named physical parameter.

    Attributes
    ----------
    name : str
    value : float
        Nominal / initial value (in ``unit``).
    lower, upper : float
        Bounds used by the fit (``-inf`` / ``inf`` for none).
    unit : str
    fixed : bool
        Fixed parameters are known a priori and not estimated.
    """

    name: str
    value: float
    lower: float = -math.inf
    upper: float = math.inf
    unit: str = ""
    fixed: bool = False

    def __post_init__(self):
        if not self.lower <= self.value <= self.upper:
            raise ValueError(
                f"parameter '{self.name}': value {self.value} outside its bounds [{self.lower}, {self.upper}]"
            )


class GreyBoxModel:
    """A continuous-time LTI model built from named physical parameters.

    Parameters
    ----------
    name : str
    params : sequence of Param
    build : callable
        ``build(theta: dict[str, float]) -> control.StateSpace`` (continuous, delay-free). ``theta`` holds
        every parameter, fixed or free.
    delay_s : float, str or Param, or a sequence of them
        Input transport delay: a known value in s, the name of a parameter in ``params`` (``'delay_s'`` or
        ``'Td'``), or a ``Param`` (added to ``params``). A sequence: one delay per input of ``build``'s system,
        the paths the one model input drives, each after its own delay (the yaw of a vehicle whose rotor pairs
        have different delays); :meth:`ss` is then the paths' sum without delays and :meth:`delay_s` the
        shortest.
    inputs, outputs : sequence of str, optional
        Signal names, for reports and model files.
    output_filter : callable, optional
        ``output_filter(dt) -> control.StateSpace``: a known discrete filter the measured output has been through
        (an autopilot's gyro low-pass), at sample time ``dt``; :meth:`discretize` puts it after the ZOH plant, as
        the filter runs on the sampled measurement (not a continuous filter inside the hold).

    Examples
    --------
    >>> m = GreyBoxModel("first-order", [Param("K", 1.0, 0, 10), Param("tau", 0.1, 1e-3, 5, "s")],
    ...                  lambda th: ct.ss(ct.tf([th["K"]], [th["tau"], 1])))
    """

    def __init__(self, name: str, params: Sequence[Param], build: Callable[[dict], ct.StateSpace],
                 delay_s: float | str | Param | Sequence = 0.0, inputs: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = None, output_filter: Callable[[float], ct.StateSpace] | None = None):
        params = list(params)
        paths = isinstance(delay_s, (list, tuple))
        delays = list(delay_s) if paths else [delay_s]
        for i, d in enumerate(delays):
            if isinstance(d, Param):
                params.append(d)
                delays[i] = d.name
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise ValueError(f"grey-box model '{name}': duplicate parameter names in {names}")
        for d in delays:
            if isinstance(d, str):
                if d not in names:
                    raise ValueError(f"grey-box model '{name}': delay parameter '{d}' is not one of {names}")
            elif d < 0:
                raise ValueError(f"grey-box model '{name}': delay must be >= 0 s, got {d}")
        delay_s = tuple(delays) if paths else delays[0]
        self.name = name
        self.params = params
        self.build = build
        self.delay = delay_s
        self.inputs = list(inputs) if inputs else None
        self.outputs = list(outputs) if outputs else None
        self.output_filter = output_filter

    # -- parameter bookkeeping -------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]

    @property
    def free(self) -> list[str]:
        """Names of the parameters that a fit estimates."""
        return [p.name for p in self.params if not p.fixed]

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"grey-box model '{self.name}' has no parameter '{name}'; parameters: {self.names}")

    def values(self) -> dict[str, float]:
        return {p.name: float(p.value) for p in self.params}

    def replace(self, **changes) -> GreyBoxModel:
        """Copy with parameter fields changed: ``m.replace(J=dict(value=0.02, fixed=True))`` or ``J=0.02``."""
        new = []
        for p in self.params:
            ch = changes.pop(p.name, None)
            if ch is None:
                new.append(p)
            elif isinstance(ch, Mapping):
                new.append(dataclasses.replace(p, **ch))
            else:
                new.append(dataclasses.replace(p, value=float(ch)))
        if changes:
            raise KeyError(f"grey-box model '{self.name}' has no parameter(s) {sorted(changes)}; "
                           f"parameters: {self.names}")
        return GreyBoxModel(self.name, new, self.build, self.delay, self.inputs, self.outputs, self.output_filter)

    def with_values(self, values: Mapping[str, float]) -> GreyBoxModel:
        return self.replace(**{k: float(v) for k, v in values.items()})

    def fix(self, *names: str) -> GreyBoxModel:
        return self.replace(**{n: {"fixed": True} for n in names})

    def unfix(self, *names: str) -> GreyBoxModel:
        return self.replace(**{n: {"fixed": False} for n in names})

    # -- models ----------------------------------------------------------------------------------
    def _theta(self, theta: Mapping[str, float] | None) -> dict[str, float]:
        th = self.values()
        if theta:
            unknown = set(theta) - set(th)
            if unknown:
                raise KeyError(f"grey-box model '{self.name}' has no parameter(s) {sorted(unknown)}")
            th.update({k: float(v) for k, v in theta.items()})
        return th

    def scaled(self, theta0: Mapping[str, float] | None = None) -> ScaledParams:
        """The free parameters as an optimiser searches them: in units of their start values (``theta0`` over
        the parameter values, clipped to the bounds), so the trust region and finite differences see comparable
        steps whether a parameter is 1e-3 kg m^2 or 1e3 N m/rad."""
        free, base = self.free, self._theta(theta0)
        lo = np.array([self.param(n).lower for n in free])
        hi = np.array([self.param(n).upper for n in free])
        x_init = np.clip(np.array([base[n] for n in free]), lo, hi)
        return ScaledParams(free, base, lo, hi, x_init, np.where(np.abs(x_init) > 0, np.abs(x_init), 1.0))

    def _paths(self, theta: Mapping[str, float] | None) -> ct.StateSpace:
        sys = as_ss(self.build(self._theta(theta)))
        if is_discrete(sys):
            raise ValueError(f"grey-box model '{self.name}': build() must return a continuous model (dt=0)")
        return sys

    def ss(self, theta: Mapping[str, float] | None = None) -> ct.StateSpace:
        """Continuous delay-free state-space model at ``theta`` (default: the parameter values); with several
        delay paths their sum."""
        sys = self._paths(theta)
        return _fan_in(sys) if isinstance(self.delay, tuple) else sys

    def path_delays_s(self, theta: Mapping[str, float] | None = None) -> list[float]:
        """The delay of each input path, s (one entry without paths)."""
        th = self._theta(theta)
        delays = self.delay if isinstance(self.delay, tuple) else (self.delay,)
        return [float(th[d]) if isinstance(d, str) else float(d) for d in delays]

    def delay_s(self, theta: Mapping[str, float] | None = None) -> float:
        """The transport delay, s; with several paths the shortest."""
        return min(self.path_delays_s(theta))

    def discretize(self, dt: float, theta: Mapping[str, float] | None = None, less_s: float = 0.0) -> ct.StateSpace:
        """Exact ZOH model at ``dt`` with the (possibly fractional) delay, less ``less_s`` (whole samples a caller
        keeps apart), then the output filter; plant states first."""
        if not isinstance(self.delay, tuple):
            return self.filtered(c2d_zoh_delay(self.ss(theta), dt, self.delay_s(theta) - less_s))
        return self.filtered(c2d_zoh_delay(self._paths(theta), dt, [d - less_s for d in self.path_delays_s(theta)]))

    def filtered(self, sysd: ct.StateSpace) -> ct.StateSpace:
        """``sysd`` (discrete) followed by the output filter at its sample time; ``sysd`` when there is none."""
        if self.output_filter is None:
            return sysd
        return ct.series(sysd, self.output_filter(float(sysd.dt)))

    def __repr__(self) -> str:
        ps = ", ".join(f"{p.name}={p.value:g}{' (fixed)' if p.fixed else ''}" for p in self.params)
        return f"GreyBoxModel({self.name!r}: {ps}; delay={self.delay!r})"


@dataclass(frozen=True)
class ScaledParams:
    """:meth:`GreyBoxModel.scaled`: the free parameters' names, the full parameter values the search starts
    from (``base``), the bounds (``lo``, ``hi``), the start (``x_init``) and the scale, in the free parameters'
    units; ``z = x / scale`` is what the optimiser moves."""

    free: list[str]
    base: dict[str, float]
    lo: np.ndarray
    hi: np.ndarray
    x_init: np.ndarray
    scale: np.ndarray

    def theta(self, z) -> dict[str, float]:
        """Every parameter's value at the scaled free parameters ``z``."""
        th = dict(self.base)
        th.update(zip(self.free, z * self.scale))
        return th


@dataclass
class GreyBoxResult:
    """Result of a grey-box fit.

    Attributes
    ----------
    model : GreyBoxModel
        The structure with the estimated values filled in.
    params : dict[str, float]
        Every parameter (estimated and fixed).
    free : list[str]
        Estimated parameters, in the order of ``cov``.
    cov : ndarray
        Covariance of the estimated parameters, ``sigma^2 (J^T J)^-1``.
    std : dict[str, float]
        Standard errors of the estimated parameters.
    ci95 : dict[str, tuple[float, float]]
        95 % confidence intervals (Student's t) of the estimated parameters.
    sys : control.StateSpace
        Continuous delay-free model at the estimate.
    delay_s : float
    dt : float
        Sample time of the data (s).
    fit_vaf : ndarray
        Variance accounted for (%) per output, on the fitted data.
    sigma2 : ndarray
        Residual variance per output.
    x0 : ndarray or None
        Estimated initial plant state.
    at_bound : list[str]
        Estimated parameters that ended on a bound (their interval is not meaningful).
    success, message, nfev, cost :
        From ``scipy.optimize.least_squares``.
    """

    model: GreyBoxModel
    params: dict
    free: list
    cov: np.ndarray
    std: dict
    ci95: dict
    sys: ct.StateSpace
    delay_s: float
    dt: float
    fit_vaf: np.ndarray
    sigma2: np.ndarray
    x0: np.ndarray | None = None
    at_bound: list = field(default_factory=list)
    success: bool = True
    message: str = ""
    nfev: int = 0
    cost: float = 0.0

    def covers(self, truth: Mapping[str, float]) -> dict[str, bool]:
        """For each estimated parameter in ``truth``: does its 95 % interval contain the true value?"""
        return {k: bool(self.ci95[k][0] <= v <= self.ci95[k][1]) for k, v in truth.items() if k in self.ci95}

    def discrete(self):
        """The fit as an ``IdentifiedModel`` at ``dt``: ZOH plant with the whole-sample part of the delay as
        ``delay`` samples; a fractional remainder stays inside ``sys`` (ZOH with input delay)."""
        d = int(np.floor(self.delay_s / self.dt + 1e-9))
        sysd = self.model.discretize(self.dt, less_s=d * self.dt)
        return IdentifiedModel(sys=sysd, delay=d, method="oe", settings={"structure": self.model.name},
                               extra={"params": dict(self.params), "ci95": dict(self.ci95),
                                      "fit_vaf": self.fit_vaf.tolist()})

    def summary(self) -> str:
        lines = [f"grey-box '{self.model.name}': VAF {', '.join(f'{v:.2f} %' for v in self.fit_vaf)}"]
        for p in self.model.params:
            v = self.params[p.name]
            if p.name in self.ci95:
                lo, hi = self.ci95[p.name]
                flag = "  (at bound)" if p.name in self.at_bound else ""
                lines.append(f"  {p.name:>10s} = {v:.6g} {p.unit}  +- {self.std[p.name]:.3g}  "
                             f"95% [{lo:.6g}, {hi:.6g}]{flag}")
            else:
                lines.append(f"  {p.name:>10s} = {v:.6g} {p.unit}  (fixed)")
        return "\n".join(lines)


def _fan_in(sys: ct.StateSpace) -> ct.StateSpace:
    """``sys`` with its inputs driven by one input (a multi-path model's paths)."""
    m = sys.ninputs
    return ct.ss(sys.A, np.asarray(sys.B) @ np.ones((m, 1)), sys.C, np.asarray(sys.D) @ np.ones((m, 1)), sys.dt)


# -- simulation ---------------------------------------------------------------------------------------

def _observability_sequence(A: np.ndarray, C: np.ndarray, N: int) -> np.ndarray:
    """``(N, p, n)``: ``C A^k`` for ``k = 0 .. N-1``, by doubling (``log2 N`` matrix products)."""
    O = C[None, :, :]
    P = A
    with np.errstate(over="ignore", invalid="ignore"):  # a trial parameter that destabilises the model diverges
        while O.shape[0] < N:
            O = np.concatenate([O, O @ P], axis=0)
            P = P @ P
    return O[:N]


def _lsim(sysd: ct.StateSpace, u: np.ndarray) -> np.ndarray:
    """Zero-state response of a small discrete system, ``u`` (N, m) -> (N, p).

    The impulse response ``D, C B, C A B, ...`` (:func:`_observability_sequence`) convolved with the input
    (``scipy.signal.oaconvolve``): vectorised, where ``dlsim`` is a Python loop, and accurate to rounding, where
    the transfer-function form (``ss2tf`` and ``lfilter``) is not: the characteristic polynomial of a model with
    a delay line (a Jordan block at z = 0) and close poles loses about seven digits, which the fits' finite-
    difference Jacobians (steps of 1e-8) then read as the response's slope.
    """
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sysd.A, sysd.B, sysd.C, sysd.D))
    p, m = D.shape
    N = u.shape[0]
    if A.shape[0] == 0 or N == 0:
        return u @ D.T
    y = np.zeros((N, p))
    with np.errstate(over="ignore", invalid="ignore"):
        h = np.concatenate([D[None], _observability_sequence(A, C, N - 1) @ B], axis=0)
        for j in range(m):
            for i in range(p):
                y[:, i] += sig.oaconvolve(h[:, i, j], u[:, j])[:N]
    return y


def _free_response_basis(sysd: ct.StateSpace, nx: int, N: int) -> np.ndarray:
    """``(N, p, nx)`` outputs of the unforced system from each unit initial state ``e_i`` (first ``nx``):
    ``C A^k e_i``."""
    A, C = np.asarray(sysd.A, float), np.asarray(sysd.C, float)
    return _observability_sequence(A, C, N)[:, :, :nx]


def simulate_greybox(model: GreyBoxModel, u, dt: float, theta: Mapping[str, float] | None = None,
                     x0=None) -> np.ndarray:
    """Output ``(N, p)`` of the grey-box model for input samples ``u`` held over ``dt`` (ZOH, delay included).

    ``x0`` is the initial state of the continuous plant (delayed inputs before the record are zero).

    Parameters
    ----------
    model : GreyBoxModel
        The structure.
    u : array_like, (N,) or (N, m)
        Input samples.
    dt : float
        Sample time, s.
    theta : dict, optional
        Parameter values (default: the model's).
    x0 : array_like, optional
        Initial state of the continuous plant.

    Returns
    -------
    ndarray, shape (N, p)

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.first_order_structure(K=2.0, tau=0.1, delay_s=0.02)
    >>> y = ident.simulate_greybox(m, np.ones(100), dt=0.01)
    >>> bool(abs(y[1, 0]) < 1e-12), round(float(y[-1, 0]), 3)  # the 2-sample delay, then 2 (1 - e^{-t/tau})
    (True, 2.0)
    """
    u2 = as_columns(u, "u")
    sysd = model.discretize(dt, theta)
    y = _lsim(sysd, u2)
    if x0 is not None:
        n = model.ss(theta).nstates
        y += _free_response_basis(sysd, n, len(u2)) @ np.asarray(x0, float).ravel()
    return y


def _controller_d(controller, dt: float) -> ct.StateSpace:
    K = as_ss(controller)
    if is_discrete(K):
        if abs(float(K.dt) - dt) > 1e-12 * max(dt, 1.0):
            raise ValueError(f"controller sample time {K.dt} s differs from the data's {dt} s")
        return K
    # A continuous controller is run as the flight computer would: discretised at the data rate
    # (Tustin keeps a stable filtered derivative stable and matches the controller's phase best).
    return ct.c2d(K, dt, method="tustin")


def _closed_loop(plant_d: ct.StateSpace, K: ct.StateSpace, feedback_output) -> ct.StateSpace:
    """Discrete closed loop ``r -> y`` (all plant outputs), plant states first.

    ``feedback_output``: one plant output index, or a sequence of them. ``K`` with one input is driven by the
    error ``r - y[feedback_output]`` (one feedback output); with ``1 + len(feedback_output)`` inputs it gets
    ``[r, y[fb_0], y[fb_1], ...]`` (the 2-DoF form of :func:`rotorlab.lti.pid2_ss`, or a PD on angle and rate).
    """
    fb = [int(feedback_output)] if np.ndim(feedback_output) == 0 else [int(i) for i in feedback_output]
    Ap, Bp, Cp, Dp = (np.asarray(M, float) for M in (plant_d.A, plant_d.B, plant_d.C, plant_d.D))
    Ak, Bk, Ck, Dk = (np.asarray(M, float) for M in (K.A, K.B, K.C, K.D))
    if np.any(Dp[fb]):
        raise ValueError("closed-loop simulation needs a strictly proper plant on the feedback output")
    if K.ninputs == 1 and len(fb) == 1:
        Br, By = Bk[:, [0]], -Bk[:, [0]]
        Dr, Dy = Dk[:, [0]], -Dk[:, [0]]
    elif K.ninputs == 1 + len(fb):
        Br, By = Bk[:, [0]], Bk[:, 1:]
        Dr, Dy = Dk[:, [0]], Dk[:, 1:]
    else:
        raise ValueError(f"controller must have 1 input (error) or {1 + len(fb)} inputs (r, y_fb); "
                         f"it has {K.ninputs}")
    cy = Cp[fb]
    # u = Ck xk + Dr r + Dy y_fb,  y_fb = cy xp (strictly proper)
    A = np.block([[Ap + Bp @ Dy @ cy, Bp @ Ck], [By @ cy, Ak]])
    B = np.vstack([Bp @ Dr, Br])
    C = np.hstack([Cp + Dp @ Dy @ cy, Dp @ Ck])
    D = Dp @ Dr
    return ct.ss(A, B, C, D, plant_d.dt)


def lift_interpolated(sys_fast: ct.StateSpace, substeps: int) -> ct.StateSpace:
    """The discrete system at ``substeps`` times ``sys_fast``'s sample time that runs ``sys_fast`` ``substeps``
    times per sample on the input interpolated linearly between samples, output taken at the samples.

    A loop that runs faster than it was logged (an autopilot at 400 Hz, its log at 25 Hz) seen at the log's
    samples: over one slow sample ``x[k+1] = Phi x[k] + G0 u[k] + G1 u[k+1]`` with ``Phi = A^n``,
    ``G0 = sum_j A^(n-1-j) B (1 - j/n)``, ``G1 = sum_j A^(n-1-j) B j/n``; the state ``xi = x - G1 u`` makes it
    causal: ``xi[k+1] = Phi xi[k] + (Phi G1 + G0) u[k]``, ``y[k] = C xi[k] + (C G1 + D) u[k]`` (first-order
    hold, as ``c2d(..., "foh")`` is for a continuous system). ``substeps = 1`` returns ``sys_fast``.

    Examples
    --------
    >>> fast = ct.ss([[0.9]], [[0.1]], [[1.0]], [[0.0]], 0.01)
    >>> slow = lift_interpolated(fast, 4)
    >>> float(slow.dt), round(float(ct.dcgain(slow)), 12)
    (0.04, 1.0)
    """
    n = int(substeps)
    if n == 1:
        return sys_fast
    A, B, C, D = (np.asarray(M, float) for M in (sys_fast.A, sys_fast.B, sys_fast.C, sys_fast.D))
    G0, G1 = np.zeros_like(B), np.zeros_like(B)
    P = np.eye(A.shape[0])  # A^(n-1-j), j from n-1 down to 0
    for j in range(n - 1, -1, -1):
        G0 += P @ B * (1.0 - j / n)
        G1 += P @ B * (j / n)
        P = A @ P
    Phi = P
    return ct.ss(Phi, Phi @ G1 + G0, C, C @ G1 + D, float(sys_fast.dt) * n)


def simulate_closed_loop(model: GreyBoxModel, controller, r, dt: float,
                         theta: Mapping[str, float] | None = None, feedback_output: int = 0,
                         substeps: int = 1) -> np.ndarray:
    """Closed-loop plant outputs ``(N, p)`` for reference samples ``r`` (loop at rest at the start); with
    ``substeps`` the loop runs at ``dt / substeps`` on ``r`` interpolated linearly (:func:`lift_interpolated`).

    Parameters
    ----------
    model : GreyBoxModel
        The plant structure.
    controller : StateSpace
        Discrete controller at ``dt`` on ``r - y`` (one input) or on ``[r; y]`` (two inputs).
    r : array_like
        Reference samples.
    dt : float
        Sample time, s.
    theta : dict, optional
        Parameter values (default: the model's).
    feedback_output : int
        The plant output fed back.
    substeps : int
        Loop steps per sample of ``r`` (a loop faster than its log: an autopilot at 400 Hz logged at 25 Hz).

    Returns
    -------
    ndarray, shape (N, p)

    Examples
    --------
    A proportional controller ``u = 2 (r - y)`` around ``1/(0.1 s + 1)``: the loop settles at 2/3 of the step.

    >>> import control as ct
    >>> from rotorlab import ident
    >>> m = ident.first_order_structure(K=1.0, tau=0.1, delay_s=0.0)
    >>> y = ident.simulate_closed_loop(m, ct.ss([], [], [], [[2.0]], 0.01), np.ones(200), dt=0.01)
    >>> round(float(y[-1, 0]), 4)
    0.6667
    """
    dtf = dt / substeps
    cl = _closed_loop(model.discretize(dtf, theta), _controller_d(controller, dtf), feedback_output)
    return _lsim(lift_interpolated(cl, substeps), as_columns(r, "r"))


# -- fitting -----------------------------------------------------------------------------------------

def _jacobian(fun, z, lo, hi, step: float = 1e-4) -> np.ndarray:
    """Central-difference Jacobian of the residual at the optimum, for the covariance.

    The optimiser's own forward differences use steps near sqrt(eps), where the ~1e-11 relative round-off
    of the simulation (transfer-function form) is amplified to ~1e-3 and can hide an unidentifiable
    direction; a 1e-4 central step keeps both round-off and truncation error near 1e-8.
    """
    cols = []
    for i in range(z.size):
        h = step * max(1.0, abs(z[i]))
        up, dn = z.copy(), z.copy()
        up[i] = min(z[i] + h, hi[i])
        dn[i] = max(z[i] - h, lo[i])
        cols.append((fun(up) - fun(dn)) / (up[i] - dn[i]))
    return np.column_stack(cols)


def _covariance(Jm, r, N, p, dof, method, name, free, rep_dev=None) -> np.ndarray:
    """Covariance of the (scaled) parameters at the least-squares optimum.

    ``'white'``: the classic ``sigma^2 (J^T J)^-1`` for white residuals. ``'hac'``: the sandwich
    ``H^-1 Omega H^-1`` with ``Omega`` the Newey-West (Bartlett-weighted) long-run covariance of the
    per-sample scores, for coloured residuals such as the ``S v`` left by closed-loop output error (the
    measurement noise fed back through the loop). Bandwidth ``sqrt(N)`` lags: it must grow with ``N`` for
    consistency and cover the loop's correlation time (a few closed-loop time constants); rules read off
    the residual autocorrelation proved erratic on such high-pass residuals.
    ``'periods'``: ``rep_dev`` (n, N * p) holds each replicate's weighted deviation from the averaged data;
    the Gauss-Newton step each replicate alone would take from the optimum, ``-H^-1 J^T dev_i``, is its
    own estimate to first order, and the covariance of their mean is their sample covariance over ``n``.
    The deviations hold the noise only: a misfit of the structure is common to every period and cancels,
    so the interval is honest for any noise colour within a period and says nothing about model error.
    """
    U, sv, Vt = np.linalg.svd(Jm, full_matrices=False)
    # the Jacobian comes from finite differences (relative error ~ sqrt(eps)), so a direction whose singular
    # value is below 1e-6 of the largest (variance 1e12 times larger, on order-one scaled parameters) is
    # treated as not identifiable rather than reported with a meaningless huge interval
    tol = sv[0] * 1e-6 if sv.size else 0.0
    if not np.all(sv > tol):
        null = Vt[-1]
        names = ", ".join(f"{n} ({c:+.2f})" for n, c in zip(free, null) if abs(c) > 0.1)
        warnings.warn(f"grey-box model '{name}': parameters not identifiable from these data; the "
                      f"direction {names} leaves the output unchanged -- fix one of them", stacklevel=4)
        return np.full((len(free),) * 2, np.inf)
    Hinv = (Vt.T / sv**2) @ Vt
    if method == "periods":
        steps = -(rep_dev @ Jm) @ Hinv
        return np.atleast_2d(np.cov(steps, rowvar=False, ddof=1)) / steps.shape[0]
    if method == "white":
        return float(r @ r) / dof * Hinv
    if method != "hac":
        raise ValueError(f"cov must be 'white', 'hac' or 'periods', got {method!r}")
    e = r.reshape(N, p)
    scores = np.einsum("kjn,kj->kn", Jm.reshape(N, p, -1), e)
    L = int(np.sqrt(N))
    Omega = scores.T @ scores
    for lag in range(1, L + 1):
        G = scores[lag:].T @ scores[:-lag]
        Omega += (1.0 - lag / (L + 1)) * (G + G.T)
    return Hinv @ Omega @ Hinv * (N * p / dof)


def _fit(model: GreyBoxModel, y: np.ndarray, dt: float, simulate, theta0, estimate_x0: bool, nx: int,
         restarts: int, rng, max_nfev, progress: bool, cov_method: str, replicates=None,
         reweight: bool = True) -> GreyBoxResult:
    if not model.free:
        raise ValueError(f"grey-box model '{model.name}': every parameter is fixed, nothing to estimate")
    sp = model.scaled(theta0)
    free, lo, hi, x_init, scale, theta_of = sp.free, sp.lo, sp.hi, sp.x_init, sp.scale, sp.theta
    N, p = y.shape
    w = np.ones(p)  # per-output weights, 1/sigma_j (re-estimated for several outputs: ML with unknown variances)

    def residual(z, want_x0=False):
        th = theta_of(z)
        ysim, basis = simulate(th)
        e = y - ysim
        x0 = None
        if basis is not None:
            Bm = (basis * w[None, :, None]).reshape(N * p, -1)
            x0, *_ = np.linalg.lstsq(Bm, (e * w).ravel(), rcond=None)
            e = e - basis @ x0
        r = (e * w).ravel()
        if not np.all(np.isfinite(r)):
            r = np.full_like(r, 1e6)
        elif np.abs(r).max() > 1e10:
            # a start that makes the simulated loop diverge: finite residuals near 1e300 overflow the
            # optimiser's squares into NaN; a plateau sends it back like a non-finite one
            r = np.full_like(r, 1e10)
        return (r, x0) if want_x0 else r

    starts = [x_init / scale]
    if restarts:
        rng = np.random.default_rng(rng)
        for _ in range(restarts):
            # random starts within a factor 3 of the initial values (log-uniform), clipped to the bounds:
            # uniform draws over wide physical bounds would mostly start far from anything sensible
            z = x_init * np.exp(rng.uniform(-np.log(3.0), np.log(3.0), x_init.size))
            z = np.where(x_init == 0, rng.uniform(0.0, 1.0, x_init.size), z)
            starts.append(np.clip(z, lo, hi) / scale)
    if p > 1:
        w = 1.0 / np.maximum(y.std(axis=0), 1e-300)
    best = None
    for z0 in tqdm(starts, desc=f"oe fit {model.name}", disable=not progress or len(starts) == 1):
        sol = opt.least_squares(residual, z0, bounds=(lo / scale, hi / scale), method="trf",
                                x_scale="jac", max_nfev=max_nfev)
        if best is None or sol.cost < best.cost:
            best = sol
    if p > 1 and reweight:
        # unknown noise variance per output: the ML estimate weights each output by its residual
        # standard deviation, so re-weight once and polish from the best start
        e = residual(best.x).reshape(N, p) / w
        w = 1.0 / np.maximum(e.std(axis=0), 1e-300)
        best = opt.least_squares(residual, best.x, bounds=(lo / scale, hi / scale), method="trf",
                                 x_scale="jac", max_nfev=max_nfev)
    r, x0 = residual(best.x, want_x0=True)
    th = theta_of(best.x)
    dof = max(N * p - len(free) - (nx if estimate_x0 else 0), 1)
    rep_dev = None if replicates is None else ((replicates - y[None]) * w).reshape(len(replicates), -1)
    cov = _covariance(_jacobian(residual, best.x, lo / scale, hi / scale), r, N, p, dof, cov_method, model.name,
                      free, rep_dev) * np.outer(scale, scale)
    std = np.sqrt(np.diag(cov))
    tq = st.t.ppf(0.975, dof if replicates is None else len(replicates) - 1)
    ci = {n: (th[n] - tq * s, th[n] + tq * s) for n, s in zip(free, std)}
    at_bound = [n for n, v, a, b in zip(free, best.x * scale, lo, hi)
                if np.isclose(v, a, rtol=1e-6, atol=0) or np.isclose(v, b, rtol=1e-6, atol=0)]
    e = r.reshape(N, p) / w
    fitted = model.with_values(th)
    return GreyBoxResult(
        model=fitted, params=th, free=list(free), cov=cov, std=dict(zip(free, std)), ci95=ci,
        sys=fitted.ss(), delay_s=fitted.delay_s(), dt=dt, fit_vaf=vaf(y, y - e),
        sigma2=e.var(axis=0, ddof=0) * (N * p) / dof, x0=x0, at_bound=at_bound, success=bool(best.success),
        message=str(best.message), nfev=int(best.nfev), cost=float(best.cost),
    )


def oe_fit(model: GreyBoxModel, u, y, dt: float, theta0: Mapping[str, float] | None = None, *,
           estimate_x0: bool = False, restarts: int = 0, rng=None, max_nfev: int | None = None,
           cov: str = "white", progress: bool = False) -> GreyBoxResult:
    """Output-error maximum-likelihood fit of a grey-box model to open-loop data.

    Parameters
    ----------
    model : GreyBoxModel
        Structure; free parameters are estimated within their bounds, fixed ones kept.
    u : array_like, (N,) or (N, m)
        Input samples, held over each sample interval (ZOH).
    y : array_like, (N,) or (N, p)
        Measured outputs at the same instants.
    dt : float
        Sample time (s).
    theta0 : dict, optional
        Initial values overriding the model's.
    estimate_x0 : bool
        Estimate the initial plant state (by variable projection) instead of starting at rest.
    restarts : int
        Extra random starts inside the bounds (seeded by ``rng``); the lowest cost wins.
    rng : int or numpy.random.Generator, optional
    max_nfev : int, optional
        Passed to ``scipy.optimize.least_squares``.
    cov : {'white', 'hac'}
        Parameter covariance: ``sigma^2 (J^T J)^-1`` for white measurement noise, or the
        Newey-West sandwich for coloured residuals (see ``_covariance``).
    progress : bool
        tqdm bar over the starts.

    Returns
    -------
    GreyBoxResult

    Examples
    --------
    A motor's first-order lag recovered from a noisy step-rich record:

    >>> from rotorlab import ident
    >>> truth = ident.first_order_structure(K=2.0, tau=0.05, delay_s=0.02)
    >>> u = np.repeat(np.random.default_rng(0).choice([0.0, 1.0], 100), 20)          # holds of 0.2 s at 100 Hz
    >>> y = ident.simulate_greybox(truth, u, dt=0.01)[:, 0] + 0.01 * np.random.default_rng(1).standard_normal(len(u))
    >>> fit = ident.oe_fit(ident.first_order_structure(K=1.0, tau=0.1, fixed=("delay_s",), delay_s=0.02), u, y, dt=0.01)
    >>> round(float(fit.params["K"]), 2), round(float(fit.params["tau"]), 3)
    (2.0, 0.05)
    """
    u2, y2 = as_columns(u, "u"), as_columns(y, "y")
    if len(u2) != len(y2):
        raise ValueError(f"u has {len(u2)} samples, y has {len(y2)}")
    nx = model.ss().nstates

    def simulate(th):
        sysd = model.discretize(dt, th)
        return _lsim(sysd, u2), (_free_response_basis(sysd, nx, len(u2)) if estimate_x0 else None)

    return _fit(model, y2, dt, simulate, theta0, estimate_x0, nx, restarts, rng, max_nfev, progress, cov)


def oe_fit_closed_loop(model: GreyBoxModel, controller, r, y, dt: float,
                       theta0: Mapping[str, float] | None = None, *, feedback_output: int = 0,
                       estimate_x0: bool = False, restarts: int = 0, rng=None, max_nfev: int | None = None,
                       cov: str = "hac", progress: bool = False, periods: int = 0,
                       replicates=None, reweight: bool = True, substeps: int = 1) -> GreyBoxResult:
    """Indirect closed-loop output-error fit: the plant is estimated through the known closed loop.

    The loop ``u = C (r - y_fb)`` (or ``u = C [r; y_fb]`` for a two-input controller such as
    :func:`rotorlab.lti.pid2_ss`) is simulated from the reference ``r`` with the plant at ``theta``, and the
    plant parameters are fitted to the measured outputs ``y`` (the TUHH procedure, doc 002 sec. 4: PRBS
    reference, known stabilising PD controller, estimate of p, J, Td).

    Parameters
    ----------
    model : GreyBoxModel
        Plant structure.
    controller : control.StateSpace or TransferFunction
        Known controller: discrete at ``dt``, or continuous (then discretised with Tustin at ``dt``).
    r : array_like, (N,)
        Reference (excitation) samples.
    y : array_like, (N,) or (N, p)
        Measured plant outputs.
    dt : float
        Sample time (s).
    feedback_output : int or sequence of int
        Which plant output(s) close the loop (a PD on angle and rate: ``(0, 1)`` with a controller on
        ``[r, angle, rate]``).
    periods : int
        0: ``r``/``y`` are a record starting with the loop at rest. ``> 0``: they are one period of a periodic
        experiment in steady state (TUHH: the PRBS response averaged over ten periods, :func:`periodic_average`);
        the loop is simulated from rest over ``periods + 1`` repetitions of ``r`` and the last one is compared,
        measured and simulated outputs each with its mean removed (constant sensor biases and trims are not
        part of the structure). ``periods`` must let the start-up transient die out.

    substeps : int
        The loop runs ``substeps`` times per data sample (a log written slower than the loop runs): the
        controller is at ``dt / substeps``, the reference is interpolated linearly between its samples and the
        outputs are compared at the samples (:func:`lift_interpolated`). Not with ``periods``.
    cov : {'hac', 'white', 'periods'}
        Default ``'hac'``: the residual of an indirect closed-loop fit is the measurement noise filtered
        by the sensitivity function, so it is coloured and ``sigma^2 (J^T J)^-1`` would understate the
        spread (with white-noise data, ``'white'`` is exact). ``'periods'`` (with ``replicates``): the
        period-to-period spread of a periodic experiment (see :func:`_covariance`); its intervals use
        Student's t with ``n - 1`` degrees of freedom. The residual-based covariances count a misfit of the
        structure as noise; this one does not.
    replicates : array_like, (n, N) or (n, N, p), optional
        With ``periods``: the single periods whose average is ``y`` (TUHH's ten), for ``cov='periods'``.
    reweight : bool
        Several outputs are weighted by ``1/std`` of each measured output; ``True`` (default) then re-weights
        once by the residual standard deviations (ML with unknown noise variances). With a structure that
        cannot fit exactly, the weights decide which value the estimate converges to; ``False`` keeps the
        signal weights, so fits of noisy and noise-free data of one experiment aim at the same value.

    Other parameters are as in :func:`oe_fit`. With ``estimate_x0`` the initial plant state is estimated
    (the controller starts at rest).

    Returns
    -------
    GreyBoxResult

    Examples
    --------
    The same lag identified through a known proportional loop ``u = 0.5 (r - y)``:

    >>> import control as ct
    >>> from rotorlab import ident
    >>> C = ct.ss([], [], [], [[0.5]], 0.01)
    >>> truth = ident.first_order_structure(K=2.0, tau=0.05, delay_s=0.0)
    >>> r = np.repeat(np.random.default_rng(0).choice([-1.0, 1.0], 100), 20)
    >>> noise = 0.01 * np.random.default_rng(1).standard_normal(len(r))
    >>> y = ident.simulate_closed_loop(truth, C, r, dt=0.01)[:, 0] + noise
    >>> start = ident.first_order_structure(K=1.0, tau=0.1, delay_s=0.0, fixed=("delay_s",))
    >>> fit = ident.oe_fit_closed_loop(start, C, r, y, dt=0.01, cov="white")
    >>> round(float(fit.params["K"]), 2), round(float(fit.params["tau"]), 3)
    (2.0, 0.05)
    """
    r2, y2 = as_columns(r, "r"), as_columns(y, "y")
    if r2.shape[1] != 1:
        raise ValueError("closed-loop fit takes one reference signal")
    if len(r2) != len(y2):
        raise ValueError(f"r has {len(r2)} samples, y has {len(y2)}")
    substeps = int(substeps)
    if substeps < 1 or (substeps > 1 and periods):
        raise ValueError(f"substeps must be >= 1 and 1 with periods; got {substeps}")
    K = _controller_d(controller, dt / substeps)
    nx = model.ss().nstates
    if (cov == "periods") != (replicates is not None) or (replicates is not None and not periods):
        raise ValueError("cov='periods' takes the replicates of a periodic experiment (periods > 0), and only it")
    if replicates is not None:
        rep = np.asarray(replicates, dtype=float)
        rep = rep.reshape(rep.shape[:2] + (-1,))
        if rep.shape[1:] != y2.shape or rep.shape[0] < 2:
            raise ValueError(f"replicates must be at least two periods shaped like y {y2.shape}; got {rep.shape}")
        replicates = rep - rep.mean(axis=1, keepdims=True)
    if periods:
        if estimate_x0:
            raise ValueError("a periodic steady-state fit has no initial state to estimate (estimate_x0=False)")
        n = len(r2)
        r_rep = np.tile(r2, (int(periods) + 1, 1))
        y2 = y2 - y2.mean(axis=0)

        def simulate(th):
            ys = _lsim(_closed_loop(model.discretize(dt, th), K, feedback_output), r_rep)[-n:]
            return ys - ys.mean(axis=0), None
    else:
        def simulate(th):
            cl = lift_interpolated(_closed_loop(model.discretize(dt / substeps, th), K, feedback_output), substeps)
            return _lsim(cl, r2), (_free_response_basis(cl, nx, len(r2)) if estimate_x0 else None)

    return _fit(model, y2, dt, simulate, theta0, estimate_x0, nx, restarts, rng, max_nfev, progress, cov,
                replicates, reweight)


def periodic_average(x, period: int, skip: int = 1):
    """Average of the whole periods of ``x`` (samples along axis 0) after the first ``skip`` periods (the
    transient); TUHH averaged ten PRBS periods to raise the signal-to-noise ratio (doc 002 sec. 4).

    Returns
    -------
    ndarray, (period,) + x.shape[1:]

    Parameters
    ----------
    x : array_like
        Samples along axis 0, a whole number of periods or more.
    period : int
        Period, samples.
    skip : int
        Leading periods left out.

    Examples
    --------
    >>> from rotorlab import ident
    >>> x = np.tile([1.0, 2.0, 3.0], 4) + np.array([9, 9, 9, 0, 0, 0, 0, 0, 0, 0, 0, 0])   # a transient in period 1
    >>> print(ident.periodic_average(x, period=3, skip=1))
    [1. 2. 3.]
    """
    return split_periods(x, period, skip).mean(axis=0)


def split_periods(x, period: int, skip: int = 1):
    """The whole periods of ``x`` (samples along axis 0) after the first ``skip`` periods, one a row: the
    replicates whose mean is :func:`periodic_average` (``oe_fit_closed_loop``'s ``replicates``).

    Returns
    -------
    ndarray, (n, period) + x.shape[1:]
        ``n`` the whole periods after the first ``skip``; a partial last period is dropped.

    Parameters
    ----------
    x : array_like
        Samples along axis 0.
    period : int
        Period, samples.
    skip : int
        Leading periods left out.

    Examples
    --------
    >>> from rotorlab import ident
    >>> ident.split_periods(np.arange(9.0), period=3, skip=1).tolist()
    [[3.0, 4.0, 5.0], [6.0, 7.0, 8.0]]
    """
    x = np.asarray(x, dtype=float)
    if not period >= 1:
        raise ValueError(f"a period is at least one sample; got {period}")
    n = x.shape[0] // period - skip
    if n < 1:
        raise ValueError(f"need at least {skip + 1} whole periods of {period} samples; got {x.shape[0]} samples")
    return x[skip * period:(skip + n) * period].reshape((n, period) + x.shape[1:])
