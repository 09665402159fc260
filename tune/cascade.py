"""The published attitude cascade (per axis) as generalised plants for tuning and analysis.

Outer 2-DoF PD on the angle (kp, kd, tf, b, c) -> rate set-point; inner 2-DoF PID on the rate
(kp, ki, kd, tf, b, c) -> command u [%]; plant G: u [%] -> q [deg/s] with an input delay, theta = q/s [deg].
Discrete designs build the continuous plant ``[q; theta] = [G; G/s] u``, discretise it with a zero-order
hold at ``dt`` (so theta is the exactly integrated rate a 50 Hz attitude estimate sees) and append the
delay as an exact ``z^-k``; continuous designs use a Pade delay. Controllers are the forward-Euler PIDs of
``rotorlab.lti.pid_tf`` / ``pid2_ss`` (realised in :class:`rotorlab.tune.blocks.PID2`). Saturation is
ignored in the linear design.

Signals: inputs ``theta_ref``, ``d_u`` (input disturbance / gust at the plant input), ``n_q`` (rate-sensor
noise), ``n`` (angle-sensor noise); outputs ``theta``, ``q``, ``u`` (plant input = controller command +
d_u), ``u_ctrl`` (controller command), ``q_ref`` (rate set-point), ``e`` (theta_ref - theta),
``theta_meas``, ``q_meas``. Loop-opening points: ``u`` (plant input: opens both loops), ``q`` (inner loop
at the rate measurement, outer loop open, as a cascade inner loop is designed on its own), ``theta`` (outer
loop at the angle measurement, inner loop closed).
"""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np

from rotorlab import lti
from rotorlab.errors import DataError, UnknownNameError
from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.tune.blocks import PID2, Structure
from rotorlab.tune.hinfstruct import closed_loop

__all__ = ["PlantModel", "plant_model", "cascade_plant", "generalised_plant", "cascade_structure",
           "gains_to_theta", "theta_to_gains", "closed_cascade", "control_sensitivity_cascade", "rate_angle_plant",
           "trapezoid", "cascade_mc", "tuhh_loop_controller", "INPUTS", "OUTPUTS", "LOOP_POINTS", "PARAM_NAMES", "PLANT_UNITS", "N_MEAS", "N_CON",
           "DT_S"]

DT_S = 0.02  # published flight-software rate (50 Hz) of both ANTEOS vehicles and TUHH: the default design rate

INPUTS = ("theta_ref", "d_u", "n_q", "n")
OUTPUTS = ("theta", "q", "u", "u_ctrl", "q_ref", "e", "theta_meas", "q_meas")
# loop point -> (points cut, injection input, signal measured before the cut)
LOOP_POINTS = {
    "u": ({"u"}, "d_u", "u_ctrl"),
    "q": ({"q", "theta"}, "n_q", "q"),
    "theta": ({"theta"}, "n", "theta"),
}
# closed-loop sensitivity at a point: injection -> signal after the injection
SENSITIVITY = {"u": ("d_u", "u"), "q": ("n_q", "q_meas"), "theta": ("n", "theta_meas")}
# the cascade controller of :func:`cascade_structure` reads N_MEAS measurements (theta_ref, theta_meas, q_ref,
# q_meas) and drives N_CON controls (q_ref_c, u_c): the partition of :func:`generalised_plant` for closed_loop
N_MEAS, N_CON = 4, 2
#: (input, output) units of the plant the cascade is tuned on: command in %, body rate in deg/s
PLANT_UNITS = ("%", "deg/s")
PARAM_NAMES = ("outer.kp", "outer.kd", "outer.tf", "outer.b", "outer.c",
               "inner.kp", "inner.ki", "inner.kd", "inner.tf", "inner.b", "inner.c")


@dataclasses.dataclass
class PlantModel:
    """Rate response ``G: u [%] -> q [deg/s]`` (continuous or discrete, delay removed) plus its input delay.

    The units are the flight software's, in which the cascade's gains are written (:data:`PLANT_UNITS`); a model
    in other units is converted before it gets here (:func:`rotorlab.tune.spec.unit_conversion`)."""

    G: object
    delay_s: float = 0.0
    name: str = "model"


def plant_model(num, den, delay_s: float = 0.0, name: str = "model", dt: float = 0.0) -> PlantModel:
    """PlantModel from transfer-function coefficients (continuous when ``dt == 0``).

    Parameters
    ----------
    num, den : sequence of float
        Numerator and denominator coefficients, highest power first (deg/s per %).
    delay_s : float
        Input delay, s (kept beside ``G``; the cascade adds it exactly when it discretises).
    name : str
        Label in goal reports.
    dt : float
        Sample time of a discrete model, s (0: continuous).

    Returns
    -------
    PlantModel

    Examples
    --------
    The published P2-A2 test-bed model, pitch command (%) to pitch rate (deg/s), 0.06 s delay:

    >>> from rotorlab import tune
    >>> plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06, name="test-bed")
    >>> plant.name, plant.delay_s, type(plant.G).__name__
    ('test-bed', 0.06, 'TransferFunction')
    """
    for tag, c in (("num", num), ("den", den)):
        if not np.all(np.isfinite(np.asarray(c, float))):
            raise ValueError(f"model '{name}': {tag} contains NaN or Inf")
    return PlantModel(ct.tf(num, den, dt) if dt else ct.tf(num, den), float(delay_s), name)


#: most samples of input delay in a discrete tuning model: every one is a state of each loop the tuner analyses,
#: whose cost is cubic in the states (2 s at 50 Hz, the model files' cap, is 100)
MAX_DELAY_SAMPLES = 200


def cascade_plant(model: PlantModel, dt: float) -> ct.StateSpace:
    """``u -> [q; theta]`` with the delay, discrete at ``dt`` (ZOH + exact z^-k) or continuous (Pade) if dt == 0.

    Parameters
    ----------
    model : PlantModel
        The rate model ``u [%] -> q [deg/s]`` and its delay.
    dt : float
        Controller sample time, s (0: continuous, the delay as a Pade approximant).

    Returns
    -------
    StateSpace
        ``u -> [q; theta]``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06)
    >>> Gp = tune.cascade_plant(plant, 0.02)            # 2 plant states, 3 delay samples, 1 integrator q -> theta
    >>> Gp.noutputs, Gp.nstates, Gp.dt
    (2, 6, 0.02)
    """
    G = lti.as_ss(model.G)
    if G.ninputs != 1 or G.noutputs != 1:
        raise ValueError(f"model '{model.name}' must be SISO u -> q, got {G.noutputs}x{G.ninputs}")
    if lti.is_discrete(G):
        G = lti.d2c_zoh(G)  # back to the continuous model it samples, so theta = q/s is integrated exactly
    A, B, C, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
    if np.any(D):
        raise ValueError(f"model '{model.name}': G must be strictly proper (a rate response to a command is)")
    n = A.shape[0]
    # augment with theta' = q
    Aa = np.block([[A, np.zeros((n, 1))], [C, np.zeros((1, 1))]])
    Ba = np.vstack([B, np.zeros((1, 1))])
    Ca = np.block([[C, np.zeros((1, 1))], [np.zeros((1, n)), np.ones((1, 1))]])
    Ga = ct.ss(Aa, Ba, Ca, np.zeros((2, 1)))
    if dt:
        if model.delay_s / dt > MAX_DELAY_SAMPLES:  # each sample is a state of every loop analysed
            raise ValueError(f"model '{model.name}': its delay of {model.delay_s:g} s is {model.delay_s / dt:.4g} "
                             f"samples of the spec's cascade.dt = {dt:g} s; expected at most {MAX_DELAY_SAMPLES} "
                             "(a larger cascade.dt or a shorter delay)")
        Ga = lti.c2d_zoh(Ga, dt)
    return lti.with_io_delay(Ga, model.delay_s)


def generalised_plant(Gp: ct.StateSpace, opened=(), inputs=INPUTS, outputs=OUTPUTS):
    """Generalised plant ``[w; q_ref_c, u_c] -> [z; theta_ref, theta_meas, q_ref, q_meas]`` for the cascade
    controller of :func:`cascade_structure`, with the loops cut at the points in ``opened``.

    At a cut point the signal downstream is the injection alone; the output of the same name still reports
    the signal before the cut.

    Parameters
    ----------
    Gp : StateSpace
        ``u -> [q; theta]`` from :func:`cascade_plant`.
    opened : sequence of str
        Loop points cut (``"theta"``, ``"q"``, ``"u"``); at a cut the signal downstream is the injection alone.
    inputs, outputs : sequence of str
        The exogenous inputs ``w`` and performance outputs ``z`` to keep.

    Returns
    -------
    StateSpace
        ``[w; q_ref_c, u_c] -> [z; theta_ref, theta_meas, q_ref, q_meas]``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> Gp = tune.cascade_plant(tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06), 0.02)
    >>> P = tune.generalised_plant(Gp, inputs=("theta_ref",), outputs=("theta",))
    >>> P.ninputs, P.noutputs                                  # [theta_ref; 2 controls] -> [theta; 4 measurements]
    (3, 5)
    """
    opened = set(opened)
    A, B, C, D = (np.asarray(M, float) for M in (Gp.A, Gp.B, Gp.C, Gp.D))
    n = A.shape[0]
    idx_w = {k: i for i, k in enumerate(INPUTS)}
    nw, nuc = len(INPUTS), N_CON
    # every signal as a row over [x, w, uc] (uc = [q_ref_c, u_c])
    def row(x=None, w=None, uc=None):
        r = np.zeros(n + nw + nuc)
        if x is not None:
            r[:n] = x
        for k, v in (w or {}).items():
            r[n + idx_w[k]] += v
        for k, v in (uc or {}).items():
            r[n + nw + k] += v
        return r

    u_p = row(w={"d_u": 1.0}, uc=({} if "u" in opened else {1: 1.0}))
    q = row(x=C[0]) + D[0, 0] * u_p
    th = row(x=C[1]) + D[1, 0] * u_p
    q_m = (0 * q if "q" in opened else q) + row(w={"n_q": 1.0})
    th_m = (0 * th if "theta" in opened else th) + row(w={"n": 1.0})
    sig = {
        "theta": th, "q": q, "u": u_p, "u_ctrl": row(uc={1: 1.0}), "q_ref": row(uc={0: 1.0}),
        "e": row(w={"theta_ref": 1.0}) - th, "theta_meas": th_m, "q_meas": q_m,
        "theta_ref": row(w={"theta_ref": 1.0}),
    }
    meas = [sig["theta_ref"], th_m, sig["q_ref"], q_m]
    wsel = [idx_w[k] for k in inputs] + [nw, nw + 1]
    Z = np.array([sig[k] for k in outputs] + meas)
    Cz, Dz = Z[:, :n], Z[:, n:][:, wsel]
    Bx = B @ u_p[None, n:][:, wsel] if n else np.zeros((0, len(wsel)))
    return ct.ss(A, Bx, Cz, Dz, Gp.dt)


def cascade_structure(dt: float, gains: AxisGains | None = None) -> Structure:
    """Controller structure: outer 2-DoF PD (inputs theta_ref, theta_meas) and inner 2-DoF PID
    (inputs q_ref, q_meas), parameters named as in :data:`PARAM_NAMES`."""
    o = gains.outer if gains else LoopGains(kp=1.0, kd=0.1, tf=0.05)
    i = gains.inner if gains else LoopGains(kp=0.3, ki=1.0, kd=0.01, tf=0.05)
    outer = PID2(o.kp, 0.0, o.kd, o.tf if o.kd else max(o.tf, dt), o.b, o.c, dt, name="outer", integral=False)
    inner = PID2(i.kp, i.ki, i.kd, i.tf if i.kd else max(i.tf, dt), i.b, i.c, dt, name="inner")
    # the realisation needs tf > dt/2 whenever a derivative state exists; fixed gains below it are invalid
    return Structure([outer, inner])


def gains_to_theta(S: Structure, gains: AxisGains) -> np.ndarray:
    th = S.values
    for loop, lg in (("outer", gains.outer), ("inner", gains.inner)):
        for k in ("kp", "ki", "kd", "tf", "b", "c"):
            name = f"{loop}.{k}"
            if name in S.names:
                th[S.names.index(name)] = getattr(lg, k)
    return th


def theta_to_gains(S: Structure, theta, name: str = "tuned", axis: str = "pitch") -> GainSet:
    d = dict(zip(S.names, np.asarray(theta, float)))

    def loop(p, outer):
        return LoopGains(kp=d[f"{p}.kp"], ki=0.0 if outer else d[f"{p}.ki"], kd=d[f"{p}.kd"], tf=d[f"{p}.tf"],
                         b=d[f"{p}.b"], c=d[f"{p}.c"])

    ax = AxisGains(outer=loop("outer", True), inner=loop("inner", False))
    return GainSet(name=name, axes={axis: ax} | ({"roll": ax} if axis == "pitch" else {}))


def check_point(point: str) -> str:
    if point not in LOOP_POINTS:
        raise UnknownNameError("loop point", point, LOOP_POINTS)
    return point


def check_signal(name: str, kind: str) -> str:
    valid = INPUTS if kind == "input" else OUTPUTS
    if name not in valid:
        raise UnknownNameError(f"{kind} signal", name, valid)
    return name


def closed_cascade(model, axis_gains, inputs, outputs, dt: float = DT_S, Gp=None):
    """Closed published cascade around ``model`` (:class:`PlantModel`) with the gains ``axis_gains``: the
    generalised plant (:func:`cascade_plant`, :func:`generalised_plant`) closed by its cascade structure, all
    closed-loop states kept. Signal names as in :data:`INPUTS` / :data:`OUTPUTS`. ``Gp`` (u -> [q; theta],
    delay included) replaces ``cascade_plant(model, dt)`` when given."""
    S = cascade_structure(dt, axis_gains)
    K = S.ss(gains_to_theta(S, axis_gains))
    Gp = cascade_plant(model, dt) if Gp is None else Gp
    return closed_loop(generalised_plant(Gp, inputs=tuple(inputs), outputs=tuple(outputs)), N_MEAS, N_CON, K)


def trapezoid(dt: float) -> ct.StateSpace:
    """``[1; I(z)]`` with ``I = dt/2 (z+1)/(z-1)``: a sampled rate and its trapezoidal integral (the angle)."""
    return ct.ss([[1.0]], [[1.0]], [[0.0], [dt]], [[1.0], [dt / 2]], dt)


def rate_angle_plant(G, delay_s: float, dt: float = DT_S) -> ct.StateSpace:
    """``u -> [q; theta]`` for a discrete rate model ``G`` with the angle as the trapezoidal integral of the
    rate and the input delay in whole samples. Used for the Monte Carlo plants ``G_nom + W_delta Delta``:
    :func:`cascade_plant` integrates exactly through ``d2c_zoh``, which has no answer when a fast pole of
    ``W_delta`` or ``Delta`` sits at z ~ 0 (e.g. a 2000 rad/s root: e^(-40) at 50 Hz)."""
    return lti.with_io_delay(ct.series(lti.as_ss(G), trapezoid(dt)), delay_s)


def control_sensitivity_cascade(model, axis_gains, dt: float = DT_S) -> ct.StateSpace:
    """``V_nom`` of ``h_lim`` for the cascade around a discrete rate model (:class:`PlantModel`): the transfer
    from the additive-uncertainty signal ``w`` at the rate-plant output to the plant input ``u``, both loops
    closed (ref. 000, robust stability analysis).

    ``w`` adds to the rate ``q`` and, through the angle's integral, to ``theta``: in the generalised plant
    that is the sensor-noise inputs ``n_q`` (added to the rate the controller sees) and ``n`` (added to the
    angle), driven by ``[1; I(z)] w`` with the trapezoidal integral ``I = dt/2 (z+1)/(z-1)``. The plant's own
    angle is the same trapezoidal integral of its rate (:func:`rate_angle_plant`), as in the Monte Carlo
    plants, so the Monte Carlo at ``h_lim`` tests exactly the small-gain bound (``cascade_plant``'s exact ZOH
    integral differs near Nyquist). The channel ``n -> u`` has a zero at z = 1 (a constant angle offset needs
    no steady command: the rate plant has no integrator), so ``V`` is stable; the cancelled integrator mode is
    removed with ``control.minreal`` after the full closed loop has been checked for internal stability.
    """
    T = closed_cascade(None, axis_gains, ("n_q", "n"), ("u",), dt, Gp=rate_angle_plant(model.G, model.delay_s, dt))
    if not lti.is_stable(T):
        raise DataError(f"the nominal cascade is unstable (spectral abscissa {lti.spectral_abscissa(T):.4g})")
    V = ct.minreal(ct.series(trapezoid(dt), T), tol=1e-7, verbose=False)
    if not lti.is_stable(V):
        raise DataError("V_nom kept the angle integrator: the angle-noise channel has no zero at z = 1")
    return V


def cascade_mc(G, axis_gains, delay_s: float, dt: float = DT_S) -> ct.StateSpace:
    """Monte Carlo closed-loop builder (:func:`rotorlab.tune.montecarlo.montecarlo`): uncertain discrete rate
    plant ``G`` -> inputs (theta_ref, d_u), outputs (theta, u)."""
    return closed_cascade(None, axis_gains, ("theta_ref", "d_u"), ("theta", "u"), dt,
                          Gp=rate_angle_plant(G, delay_s, dt))


def tuhh_loop_controller(axis_gains, dt: float = DT_S) -> ct.StateSpace:
    """The standard cascade flown in the TUHH closed-loop campaign as a 2-input controller ``u = K [r; q]``
    (``r`` = angle set-point in deg, ``q`` = measured rate in deg/s), the form
    :func:`rotorlab.ident.oe_fit_closed_loop` takes with the rate as feedback output.

    The flight software feeds the outer PD with the IMU angle; the closed-loop fit feeds back the rate only,
    so the angle is rebuilt from it with the trapezoidal integrator ``dt/2 (z+1)/(z-1)`` (the integral of
    the sampled rate, second-order accurate; the grey-box plant's own angle state is the exact integral).
    """
    o, i = axis_gains.outer, axis_gains.inner
    Co = lti.as_ss(lti.pid2_ss(o.kp, 0.0, o.kd, o.tf, o.b, o.c, dt))
    Ci = lti.as_ss(lti.pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, dt))
    Co = ct.ss(Co.A, Co.B, Co.C, Co.D, dt, inputs=["r", "theta"], outputs=["q_ref"], name="outer")
    Ci = ct.ss(Ci.A, Ci.B, Ci.C, Ci.D, dt, inputs=["q_ref", "q"], outputs=["u"], name="inner")
    integ = ct.ss(ct.tf([dt / 2, dt / 2], [1.0, -1.0], dt), inputs=["q"], outputs=["theta"], name="angle")
    return ct.interconnect([Co, Ci, integ], inplist=["r", "q"], outlist=["u"], dt=dt)
