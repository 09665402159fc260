"""Shipped grey-box structures: the published pitch model with IMU mount (doc 000/001), the TUHH per-axis
model (doc 002), the twin's rigid-body-on-elastic-rig model, the published second-order rate form and a
first-order motor.

Each function returns a :class:`rotorlab.ident.greybox.GreyBoxModel` whose default values are a sensible
starting point; override any of them with keyword arguments (a number sets the value, a ``Param`` replaces
the parameter, ``fixed=[...]`` lists the parameters known a priori).
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np

from rotorlab.ident.greybox import GreyBoxModel, Param

__all__ = [
    "pitch_structure",
    "tuhh_axis_structure",
    "tuhh_torque_gain",
    "rigid_rig_structure",
    "rigid_rig_tf_coefficients",
    "rate_tf_structure",
    "first_order_structure",
    "TUHH_TABLE",
]

INF = math.inf


def _apply(params: list[Param], overrides: dict, fixed) -> list[Param]:
    out = []
    names = {p.name for p in params}
    unknown = (set(overrides) | set(fixed or ())) - names
    if unknown:
        raise KeyError(f"unknown parameter(s) {sorted(unknown)}; parameters: {sorted(names)}")
    for p in params:
        v = overrides.get(p.name)
        if isinstance(v, Param):
            p = v
        elif v is not None:
            p = dataclasses.replace(p, value=float(v))
        if fixed is not None:
            p = dataclasses.replace(p, fixed=p.name in fixed)
        out.append(p)
    return out


def pitch_structure(I_yy: float = 0.25, fixed=None, **values) -> GreyBoxModel:
    """Published P2-A2 pitch structure on the test-bed with the IMU vibration mount (doc 000 p. "Grey-box",
    doc 001 eq. for ``I_yy q' = ...``):

    ``I_yy q' = M_q q + M_u u(t - tau) + k (theta_P - theta) + c (q_P - q)``,
    ``J q_P' = -k (theta_P - theta) - c (q_P - q)``, state ``[q, q_P, theta, theta_P]``, output ``q_P``.

    Parameters
    ----------
    I_yy : float
        Vehicle pitch inertia (kg m^2), known from a separate test (doc 000: "obtained from previously
        dedicated identification"); the published value is not given, 0.25 kg m^2 is an estimate for a 5 kg
        vehicle with 0.415 m arms.
    fixed : iterable of str, optional
        Parameters to hold (default: ``I_yy`` and ``tau``).
    **values
        Overrides of ``M_q`` (moment per pitch rate, < 0: damping), ``M_u`` (control moment per unit input),
        ``J`` (IMU mount inertia), ``k``, ``c`` (mount stiffness and damping), ``tau`` (delay, s; published
        0.06 s). Units follow the data: with q in deg/s and u in %, moments are in kg m^2 deg/s^2.

    Notes
    -----
    ``q_P/u = M_u (c s + k) / (I J s^3 + (c (I+J) - J M_q) s^2 + (k (I+J) - M_q c) s - M_q k)``: five
    coefficients for the five unknowns ``(M_q, M_u, J, k, c)``, identifiable with ``I_yy`` known. The
    common-mode angle ``theta = theta_P`` is an unobservable zero eigenvalue of the published 4-state form;
    fits and norms handle it (variable projection, minimal realisations).

    Returns
    -------
    GreyBoxModel
        Input the pitch command, output the IMU-mount rate ``q_P``; ``I_yy`` and the delay fixed by default.

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.pitch_structure()
    >>> m.free, m.outputs
    (['M_q', 'M_u', 'J', 'k', 'c'], ['q_P'])
    """
    params = _apply([
        Param("I_yy", I_yy, 1e-6, INF, "kg m^2", fixed=True),
        Param("M_q", -1.2, -INF, 0.0, "kg m^2/s"),
        Param("M_u", 3.0, 0.0, INF, "kg m^2 deg/s^2 per %"),
        Param("J", 0.02, 1e-6, INF, "kg m^2"),
        Param("k", 2.0, 1e-9, INF, "kg m^2/s^2"),
        Param("c", 0.1, 1e-9, INF, "kg m^2/s"),
        Param("tau", 0.06, 0.0, 1.0, "s", fixed=True),
    ], values, fixed if fixed is not None else ("I_yy", "tau"))

    def build(th):
        I, Mq, Mu, J, k, c = (th[n] for n in ("I_yy", "M_q", "M_u", "J", "k", "c"))
        A = np.array([
            [Mq / I - c / I, c / I, -k / I, k / I],
            [c / J, -c / J, k / J, -k / J],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
        ])
        # The published A prints the first row as [M_q/I, -c/I, -k/I, k/I]; expanding the printed equation
        # c (q_P - q) gives -c/I on q and +c/I on q_P, which is what we use (the printed signs would make the
        # mount an energy source).
        B = np.array([[Mu / I], [0.0], [0.0], [0.0]])
        C = np.array([[0.0, 1.0, 0.0, 0.0]])
        return ct.ss(A, B, C, np.zeros((1, 1)))

    return GreyBoxModel("pitch-imu", params, build, delay_s="tau", inputs=["u"], outputs=["q_P"])


# TUHH table 1 (doc 002). The paper prints p < 0 with the motor model |p|/(s + p); the physically
# consistent reading is a STABLE first-order motor with its pole at s = -|p|, i.e. |p|/(s + |p|), so the
# parameter here is the magnitude |p| > 0. The yaw zero is likewise read as (s + |z|), a left-half-plane
# zero from the rotor reaction torque J_r Omega' (a derivative action, doc 002 eq. 8).
TUHH_TABLE = {
    "roll": {"J": 0.0181, "p": 27.106, "Td": 0.024},
    "pitch": {"J": 0.0196, "p": 26.963, "Td": 0.028},
    "yaw": {"J": 0.0273, "p": 7.171, "z": 2.434, "Td": 0.016},
}


def tuhh_torque_gain(axis: str, *, C_T: float = 0.0157, C_Q: float = 0.0015, arm_m: float = 0.23,
                     radius_m: float = 0.127, a0: float = 701.2, a1: float = 0.8069, a2: float = -34.15,
                     b_hover: float = 0.6, rho: float = 1.225) -> float:
    """A-priori torque per unit motor command ``K`` (N m) of the TUHH quadrotor (doc 002 sec. 2.2-3).

    Thrust ``T = C_T rho A R^2 Omega^2`` and torque ``Q = C_Q rho A R^3 Omega^2`` with ``A = pi R^2``, speed
    map ``Omega(b) = a0 b^a1 + a2``, linearised at ``b_hover``: ``dOmega/db = a0 a1 b_H^(a1-1)``. The axis
    command is applied differentially, ``+b`` and ``-b`` on the motors of each opposite pair (the paper does
    not print its mixer; this is the usual one), so roll/pitch ``K = 2 l dT/db`` and yaw ``K = 4 dQ/db``.
    ``rho`` (kg/m^3) is not printed in the paper; sea-level air is assumed.
    """
    area = math.pi * radius_m**2
    omega_h = a0 * b_hover**a1 + a2
    domega_db = a0 * a1 * b_hover ** (a1 - 1.0)
    dT = 2.0 * C_T * rho * area * radius_m**2 * omega_h * domega_db
    dQ = 2.0 * C_Q * rho * area * radius_m**3 * omega_h * domega_db
    if axis in ("roll", "pitch"):
        return 2.0 * arm_m * dT
    if axis == "yaw":
        return 4.0 * dQ
    raise KeyError(f"unknown axis '{axis}'; valid axes: pitch, roll, yaw")


def tuhh_axis_structure(axis: str = "pitch", outputs=("angle",), K: float | None = None, fixed=None,
                        **values) -> GreyBoxModel:
    """TUHH per-axis model (doc 002 eq. 13): ``angle/b = K |p|/(s + |p|) e^(-s Td) / (J s^2)``; yaw
    ``K (s + z) |p|/(s + |p|) e^(-s Td) / (J s^2)``.

    Parameters
    ----------
    axis : {'roll', 'pitch', 'yaw'}
        Initial values come from the published table 1.
    outputs : tuple of {'angle', 'rate'}
        Measured outputs (the paper uses both, angle first).
    K : float, optional
        Torque per unit command (N m); default :func:`tuhh_torque_gain` (a-priori, fixed).
    fixed : iterable of str, optional
        Parameters to hold (default ``K``).
    **values
        Overrides of ``J`` (kg m^2), ``p`` (motor pole magnitude, 1/s), ``z`` (yaw zero, 1/s), ``Td`` (s).

    Notes
    -----
    From angle (or rate) data only the ratio ``K/J`` (angular acceleration per unit command, rad/s^2) is
    identifiable: ``K`` and ``J`` scale the response identically. As TUHH did, ``K`` is fixed from the
    a-priori thrust/torque data and ``J`` is estimated, so ``J_hat = K / (K/J)_hat``; a fit with both free
    reports them as not identifiable.

    Returns
    -------
    GreyBoxModel
        Input the motor command ``b``, outputs as asked; ``K`` fixed by default.

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.tuhh_axis_structure("pitch", outputs=("angle", "rate"))
    >>> m.free, m.outputs
    (['J', 'p', 'Td'], ['pitch_angle', 'pitch_rate'])
    """
    if axis not in TUHH_TABLE:
        raise KeyError(f"unknown axis '{axis}'; valid axes: {', '.join(TUHH_TABLE)}")
    bad = set(outputs) - {"angle", "rate"}
    if bad or not outputs:
        raise ValueError(f"outputs must be a non-empty tuple of 'angle'/'rate', got {outputs!r}")
    tab = TUHH_TABLE[axis]
    K = tuhh_torque_gain(axis) if K is None else float(K)
    plist = [
        Param("K", K, 1e-9, INF, "N m", fixed=True),
        Param("J", tab["J"], 1e-6, INF, "kg m^2"),
        Param("p", tab["p"], 1e-3, 1e4, "1/s"),
        Param("Td", tab["Td"], 0.0, 0.5, "s"),
    ]
    yaw = axis == "yaw"
    if yaw:
        plist.insert(3, Param("z", tab["z"], 0.0, 1e4, "1/s"))
    params = _apply(plist, values, fixed if fixed is not None else ("K",))
    outputs = tuple(outputs)

    def build(th):
        K_, J, p = th["K"], th["J"], th["p"]
        z = th["z"] if yaw else 0.0
        # states: motor torque m, integral part xi (yaw zero), angle; rate = m/J + xi (yaw) or xi (roll/pitch)
        if yaw:
            A = np.array([[-p, 0.0, 0.0], [z / J, 0.0, 0.0], [1.0 / J, 1.0, 0.0]])
            rate = np.array([1.0 / J, 1.0, 0.0])
        else:
            A = np.array([[-p, 0.0, 0.0], [1.0 / J, 0.0, 0.0], [0.0, 1.0, 0.0]])
            rate = np.array([0.0, 1.0, 0.0])
        B = np.array([[p * K_], [0.0], [0.0]])
        rows = {"angle": np.array([0.0, 0.0, 1.0]), "rate": rate}
        C = np.vstack([rows[o] for o in outputs])
        return ct.ss(A, B, C, np.zeros((len(outputs), 1)))

    return GreyBoxModel(f"tuhh-{axis}", params, build, delay_s="Td", inputs=[f"b_{axis}"],
                        outputs=[f"{axis}_{o}" for o in outputs])


def rigid_rig_structure(fixed=None, **values) -> GreyBoxModel:
    """The twin's pitch structure: rigid airframe on an elastic rig.

    Airframe (inertia ``J_a``, rotor damping ``d_a``, control moment ``M_u u``) coupled through a
    spring-damper ``(k, c)`` to a massless gimbal ring with viscous bearing damping ``d_b``; output the
    airframe rate. With ``S = d_b + c``:

    ``q/u = M_u (S s + k) / (J_a S s^2 + (J_a k + d_a S + d_b c) s + (d_a + d_b) k)``, i.e.
    ``K (s + z)/(s^2 + a s + b)`` with ``K = M_u/J_a``, ``z = k/S``, ``a = (J_a k + d_a S + d_b c)/(J_a S)``,
    ``b = (d_a + d_b) k / (J_a S)`` (:func:`rigid_rig_tf_coefficients`).

    Four transfer-function coefficients cannot give six parameters: by default ``J_a`` (from CAD or a
    pendulum test) and ``d_b`` (bearing spec) are fixed, leaving ``(d_a, k, c, M_u)``, locally identifiable.
    Defaults reproduce the published P2-A2 test-bed model ``12.517 (s + 2.906)/(s^2 + 5.583 s + 21.3)``
    (doc 000) with ``J_a = 0.25`` and ``d_b = 1.2`` assumed; delay ``delay_s`` 0.06 s (fixed).

    Parameters
    ----------
    fixed : sequence of str, optional
        Parameters kept at their values during a fit (default ``J_a``, ``d_b`` and the delay).
    **values : float
        Initial (or fixed) values: ``J_a``, ``d_a``, ``d_b``, ``k``, ``c``, ``M_u``, ``delay_s``.

    Returns
    -------
    GreyBoxModel

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> m = ident.rigid_rig_structure()
    >>> tf = ct.ss2tf(m.build(m.values()))                     # the published test-bed model at the defaults
    >>> print(np.round(tf.num[0][0], 2), np.round(tf.den[0][0], 2))
    [12.52 36.37] [ 1.    5.58 21.3 ]
    """
    params = _apply([
        Param("J_a", 0.25, 1e-6, INF, "kg m^2"),
        Param("d_a", 0.63245, 0.0, INF, "N m s/rad"),
        Param("k", 3.59772, 1e-9, INF, "N m/rad"),
        Param("c", 0.038026, 0.0, INF, "N m s/rad"),
        Param("d_b", 1.2, 0.0, INF, "N m s/rad"),
        Param("M_u", 3.12925, -INF, INF, "N m per unit input"),
        Param("delay_s", 0.06, 0.0, 1.0, "s"),
    ], values, fixed if fixed is not None else ("J_a", "d_b", "delay_s"))

    def build(th):
        Ja, da, k, c, db, Mu = (th[n] for n in ("J_a", "d_a", "k", "c", "d_b", "M_u"))
        S = db + c
        if S <= 0:
            raise ValueError("rigid-rig structure needs d_b + c > 0 (the massless ring needs damping)")
        # states: airframe rate q and spring deflection delta = theta_a - theta_ring; the massless ring
        # moves at q_r = (k delta + c q)/S (its torque balance), so delta' = q - q_r
        A = np.array([
            [-(da + c - c * c / S) / Ja, -(k - c * k / S) / Ja],
            [1.0 - c / S, -k / S],
        ])
        B = np.array([[Mu / Ja], [0.0]])
        C = np.array([[1.0, 0.0]])
        return ct.ss(A, B, C, np.zeros((1, 1)))

    return GreyBoxModel("rigid-rig", params, build, delay_s="delay_s", inputs=["u"], outputs=["q"])


def rigid_rig_tf_coefficients(theta) -> dict[str, float]:
    """``K, z, a, b`` of ``K (s + z)/(s^2 + a s + b)`` for rigid-rig parameter values ``theta``."""
    Ja, da, k, c, db, Mu = (float(theta[n]) for n in ("J_a", "d_a", "k", "c", "d_b", "M_u"))
    S = db + c
    return {"K": Mu / Ja, "z": k / S, "a": (Ja * k + da * S + db * c) / (Ja * S), "b": (da + db) * k / (Ja * S)}


def rate_tf_structure(fixed=None, **values) -> GreyBoxModel:
    """The published black-box rate form ``q/u = K (s + z)/(s^2 + a s + b) e^(-s delay_s)`` (doc 000 PBSID
    models), parametrised directly; defaults are the P2-A2 test-bed model, delay 0.06 s fixed.

    Parameters
    ----------
    fixed : sequence of str, optional
        Parameters kept at their values during a fit (default: the delay).
    **values : float
        Initial (or fixed) values by name: ``K``, ``z``, ``a``, ``b``, ``delay_s``.

    Returns
    -------
    GreyBoxModel

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.rate_tf_structure()
    >>> m.free, m.param("b").value
    (['K', 'z', 'a', 'b'], 21.3)
    """
    params = _apply([
        Param("K", 12.517, -INF, INF, "(deg/s)/(% s)"),
        Param("z", 2.906, -INF, INF, "1/s"),
        Param("a", 5.583, -INF, INF, "1/s"),
        Param("b", 21.3, -INF, INF, "1/s^2"),
        Param("delay_s", 0.06, 0.0, 1.0, "s"),
    ], values, fixed if fixed is not None else ("delay_s",))

    def build(th):
        return ct.ss(ct.tf([th["K"], th["K"] * th["z"]], [1.0, th["a"], th["b"]]))

    return GreyBoxModel("rate-tf", params, build, delay_s="delay_s", inputs=["u"], outputs=["q"])


def first_order_structure(fixed=None, **values) -> GreyBoxModel:
    """First-order lag with delay ``K e^(-s delay_s)/(tau s + 1)`` (motor speed per throttle command).

    Parameters
    ----------
    fixed : sequence of str, optional
        Parameters kept at their values during a fit.
    **values : float
        Initial (or fixed) values by name: ``K``, ``tau``, ``delay_s``.

    Returns
    -------
    GreyBoxModel

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.first_order_structure(K=2.0, tau=0.05)
    >>> m.names, m.free
    (['K', 'tau', 'delay_s'], ['K', 'tau', 'delay_s'])
    """
    params = _apply([
        Param("K", 1.0, -INF, INF, "output per input"),
        Param("tau", 0.05, 1e-5, 100.0, "s"),
        Param("delay_s", 0.0, 0.0, 10.0, "s"),
    ], values, fixed)

    def build(th):
        return ct.ss([[-1.0 / th["tau"]]], [[th["K"] / th["tau"]]], [[1.0]], [[0.0]])

    return GreyBoxModel("first-order", params, build, delay_s="delay_s", inputs=["u"], outputs=["y"])
