"""Full-order H-inf attitude designs of the TUHH quadrotor (ref. 002) and Glover-McFarlane loop shaping.

TUHH axis model (ref. 002, eq. 13 and tables 1-2)::

    angle / b = K |p| / (s + |p|) * exp(-s Td) / (J s^2)        (yaw: times (s + |z|))

The tables list the motor pole and yaw zero as negative numbers (p = -27.106, z = -2.434); with the
paper's ``|p|/(s + p)`` read literally the motor would be unstable, so we take them as root *locations*
(pole at s = -27.106, zero at s = -2.434), the physically consistent reading.

Torque gain ``K`` (N m per unit command ``b``), from eqs. (3)-(4) linearised at the hover command b_H:
``Omega_H = a0 b_H^a1 + a2``, ``Gamma = dOmega/db = a0 a1 b_H^(a1-1)``,
``dT/db = 2 C_T rho A R^2 Omega_H Gamma`` with ``A = pi R^2`` and rho = 1.225 kg/m^3, and the moment of
one rotor's thrust change about the centre, ``K = l dT/db`` (``tau_x = l (T3 - T1)`` with ``b`` the
command increment of one motor; the paper's K b is per motor command). Yaw: ``K = dQ/db`` of one rotor
(``Q = C_Q rho A R^3 Omega^2``) and the extra identification factor K~_z is taken as 1 (not published).
Input disturbances "x % of maximum thrust/motor power" are read as ``x`` of the full motor command range
``b in [0, 1]``, i.e. ``d = x`` in command units at the plant input; the axis command saturates at
``+-(1 - b_H) = +-0.4`` (a motor command cannot exceed 1), so a 30 % disturbance leaves 0.1 of authority.
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import numpy as np
import scipy.linalg as sla

from rotorlab import lti
from rotorlab.errors import DataError, UnknownNameError

__all__ = [
    "TUHH_AXES", "TUHH", "tuhh_torque_gain", "tuhh_axis_plant", "modified_pid",
    "MixedSensitivityWeights", "tuhh_generalized_plant", "hinf_mixed_sensitivity", "glover_mcfarlane",
]

#: ref. 002 table 1 (p, z as root locations in 1/s, see module docstring)
TUHH_AXES = {
    "roll": {"J": 0.0181, "p": -27.106, "z": None, "Td": 0.024},
    "pitch": {"J": 0.0196, "p": -26.963, "z": None, "Td": 0.028},
    "yaw": {"J": 0.0273, "p": -7.171, "z": -2.434, "Td": 0.016},
}
#: ref. 002 table 2 (SI units) plus sea-level air density
TUHH = {"arm_m": 0.23, "R_m": 0.127, "C_T": 0.0157, "C_Q": 0.0015, "a0": 701.2, "a1": 0.8069, "a2": -34.15,
        "b_H": 0.6, "rho": 1.225}


def _axis(axis: str) -> dict:
    if axis not in TUHH_AXES:
        raise UnknownNameError("axis", axis, TUHH_AXES)
    return TUHH_AXES[axis]


def _omega(b: float) -> float:
    return TUHH["a0"] * b ** TUHH["a1"] + TUHH["a2"]


def tuhh_torque_gain(axis: str = "pitch") -> float:
    """Moment per unit motor command, N m (roll/pitch: ``l dT/db``; yaw: ``dQ/db``) at hover.

    Parameters
    ----------
    axis : {'roll', 'pitch', 'yaw'}

    Returns
    -------
    float
        N m per unit motor command.

    Examples
    --------
    >>> from rotorlab import tune
    >>> bool(tune.tuhh_torque_gain("pitch") > 0), bool(tune.tuhh_torque_gain("yaw") < tune.tuhh_torque_gain("pitch"))
    (True, True)
    """
    _axis(axis)
    R, bH = TUHH["R_m"], TUHH["b_H"]
    area = math.pi * R * R
    gamma = TUHH["a0"] * TUHH["a1"] * bH ** (TUHH["a1"] - 1.0)
    w_h = _omega(bH)
    if axis == "yaw":
        return 2 * TUHH["C_Q"] * TUHH["rho"] * area * R ** 3 * w_h * gamma
    return TUHH["arm_m"] * 2 * TUHH["C_T"] * TUHH["rho"] * area * R ** 2 * w_h * gamma


def tuhh_axis_plant(axis: str = "pitch", pade_order: int = 3, delay: bool = True,
                    regularize: float = 0.0) -> ct.StateSpace:
    """TUHH axis model from command ``b`` to ``[angle (rad), rate (rad/s)]``, continuous.

    Parameters
    ----------
    axis : 'roll', 'pitch' or 'yaw'.
    pade_order : order of the Pade approximation of the delay ``Td`` (``delay=False`` leaves it out, e.g.
        to add it exactly in a discrete simulation).
    regularize : shift of the two integrator poles to ``s = -regularize`` (1/s), for H-inf synthesis.

    Returns
    -------
    StateSpace
        Continuous, input ``b``, outputs ``[angle (rad), rate (rad/s)]``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> G = tune.tuhh_axis_plant("pitch", delay=False)         # K |p|/(s + |p|) / (J s^2) and its rate
    >>> G.noutputs, G.nstates
    (2, 3)
    """
    par = _axis(axis)
    k = tuhh_torque_gain(axis)
    p = abs(par["p"])
    num = [k * p / par["J"]]
    if par["z"] is not None:
        num = np.polymul(num, [1.0, abs(par["z"])])
    e = regularize
    # state order: motor, rate, angle; rate = (num part)/(s+e) of the motor torque
    lag = lti.as_ss(ct.tf([p], [1.0, p]))
    rate = lti.as_ss(ct.tf(np.asarray(num, float) / p, [1.0, e]))
    integ = ct.ss([[-e]], [[1.0]], [[1.0]], [[0.0]])
    g_rate = ct.series(lag, rate)
    G = ct.ss(*_stack_rate_angle(g_rate, integ))
    if delay and par["Td"] > 0:
        G = lti.with_io_delay(G, par["Td"], pade_order=pade_order)
    G.output_labels = ["angle", "rate"]
    G.input_labels = ["b"]
    return G


def _stack_rate_angle(g_rate, integ):
    """[angle; rate] of ``integ * g_rate`` and ``g_rate`` sharing states."""
    A1, B1, C1, D1 = (np.asarray(M, float) for M in (g_rate.A, g_rate.B, g_rate.C, g_rate.D))
    a, b, c = float(integ.A[0, 0]), float(integ.B[0, 0]), float(integ.C[0, 0])
    n = A1.shape[0]
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = A1
    A[n, :n] = b * C1[0]
    A[n, n] = a
    B = np.vstack([B1, b * D1])
    C = np.zeros((2, n + 1))
    C[0, n] = c
    C[1, :n] = C1[0]
    D = np.array([[0.0], [D1[0, 0]]])
    return A, B, C, D


def modified_pid(kp: float, ki: float, kd: float) -> ct.StateSpace:
    """The 'modified PID' of ref. 002 fig. 4(b) as a 1x2 controller on ``[r - angle, -rate]``:
    ``u = kp e + ki/s e + kd (-rate)`` (derivative from the measured rate, so the D part is a gain).

    Parameters
    ----------
    kp, ki, kd : float
        Proportional and integral gains on the angle error and the gain on the measured rate.

    Returns
    -------
    StateSpace
        Continuous, inputs ``[r - angle, -rate]``, output ``u``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> K = tune.modified_pid(kp=2.0, ki=1.0, kd=0.3)
    >>> K.ninputs, K.noutputs, K.nstates                     # [r - angle, -rate] -> u, one integrator
    (2, 1, 1)
    """
    return ct.ss([[0.0]], [[1.0, 0.0]], [[ki]], [[kp, kd]])


@dataclasses.dataclass(frozen=True)
class MixedSensitivityWeights:
    """Weights of the TUHH generalised plant (ref. 002 fig. 4a, reconstructed from the text).

    ``W_S(s) = (s/M_s + w_s) / (s + w_s eps_s)``: sensitivity weight on the angle error (integral action
    as ``eps_s -> 0``; ``w_s`` rad/s sets the bandwidth). ``W_K(s) = (s + w_k) / (s/m_k + w_k/l_k)``:
    gain ``l_k`` below ``w_k`` rad/s rising to ``m_k`` above (penalises control beyond the bandwidth).
    ``W_T``: static weight on the angle output (overshoot). ``V_r = (V_r1, V_r2)``: prefilters of the
    angle and rate references; ``V_d``: input-disturbance prefilter (command units).

    The defaults were tuned on the pitch axis (scan of ``w_s``, ``w_k``, ``V_d``) for the ~200 ms rise time
    on a 10 deg step that ref. 002 reports; see tests/test_tune_loopshaping.py for the resulting figures.
    """

    M_s: float = 2.0
    w_s: float = 5.0
    eps_s: float = 1e-4
    w_k: float = 20.0
    l_k: float = 0.05
    m_k: float = 2.0
    W_T: float = 0.1
    V_r1: float = 1.0
    V_r2: float = 0.1
    V_d: float = 0.05

    def ws(self) -> ct.TransferFunction:
        return ct.tf([1.0 / self.M_s, self.w_s], [1.0, self.w_s * self.eps_s])

    def wk(self) -> ct.TransferFunction:
        return ct.tf([1.0, self.w_k], [1.0 / self.m_k, self.w_k / self.l_k])


def tuhh_generalized_plant(G, weights: MixedSensitivityWeights = MixedSensitivityWeights()) -> ct.StateSpace:
    """Generalised plant with exogenous ``w = (r_angle, r_rate, d)``, control ``u``; performance outputs
    ``z = (W_S e_angle, W_K u, W_T angle)``; measurements ``e = (V_r1 r_angle - angle, V_r2 r_rate - rate)``.
    The plant input is ``u + V_d d``. ``G`` maps ``u`` to ``[angle, rate]`` (:func:`tuhh_axis_plant`).
    Input order ``(r_angle, r_rate, d, u)``, output order ``(z1, z2, z3, e_angle, e_rate)``.

    Parameters
    ----------
    G : StateSpace
        ``u -> [angle, rate]`` (:func:`tuhh_axis_plant`; regularised for a synthesis).
    weights : MixedSensitivityWeights
        The weights of ref. 002.

    Returns
    -------
    StateSpace
        Inputs ``(r_angle, r_rate, d, u)``, outputs ``(z1, z2, z3, e_angle, e_rate)``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> P = tune.tuhh_generalized_plant(tune.tuhh_axis_plant("pitch", regularize=1e-3))
    >>> P.ninputs, P.noutputs               # (r_angle, r_rate, d, u) -> (z1, z2, z3, e_angle, e_rate)
    (4, 5)
    """
    G = lti.as_ss(G)
    if (G.noutputs, G.ninputs) != (2, 1):
        raise DataError(f"the TUHH generalised plant needs G: b -> [angle, rate] (2x1); got {G.noutputs}x{G.ninputs}")
    w = weights
    Gs = ct.ss(G.A, G.B, G.C, G.D, inputs=["ug"], outputs=["angle", "rate"], name="G")
    Ws = ct.ss(lti.as_ss(w.ws()), inputs=["e1"], outputs=["z1"], name="WS")
    Wk = ct.ss(lti.as_ss(w.wk()), inputs=["u"], outputs=["z2"], name="WK")
    Wt = ct.ss([], [], [], [[w.W_T]], inputs=["angle"], outputs=["z3"], name="WT")
    # sums: e1 = V_r1 r1 - angle, e2 = V_r2 r2 - rate, ug = u + V_d d
    S = ct.ss([], [], [], [[w.V_r1, 0, 0, 0, -1, 0], [0, w.V_r2, 0, 0, 0, -1], [0, 0, w.V_d, 1, 0, 0]],
              inputs=["r1", "r2", "d", "u", "angle", "rate"], outputs=["e1", "e2", "ug"], name="sum")
    P = ct.interconnect([Gs, Ws, Wk, Wt, S], inplist=["r1", "r2", "d", "u"],
                        outlist=["z1", "z2", "z3", "e1", "e2"], check_unused=False)
    return ct.ss(P.A, P.B, P.C, P.D)


def hinf_mixed_sensitivity(axis: str = "pitch", weights: MixedSensitivityWeights = MixedSensitivityWeights(),
                           pade_order: int = 2, regularize: float = 1e-3):
    """Full-order H-inf mixed-sensitivity controller for a TUHH axis (ref. 002 sec. 5), by ``control.hinfsyn``.

    The double integrator is regularised to poles at ``s = -regularize`` (1/s) for the synthesis only: the
    Riccati solvers need a plant without imaginary-axis poles shared with the sensitivity weight's
    near-integrator; the controller is then checked on the exact double integrator by the caller.

    Parameters
    ----------
    axis : {'roll', 'pitch', 'yaw'}
        The TUHH axis (:func:`tuhh_axis_plant`).
    weights : MixedSensitivityWeights
        Performance and input weights (ref. 002's by default).
    pade_order : int
        Order of the Pade approximant of the axis delay in the synthesis model.
    regularize : float
        Where the double integrator's poles are moved for the synthesis, 1/s.

    Returns
    -------
    K : control.StateSpace, 1x2, from ``[r - angle (rad), -rate (rad/s)]`` (i.e. ``e`` with ``r_rate = 0``)
        to the axis command ``u`` (negative feedback via ``e``).
    gamma : achieved closed-loop H-inf norm of the weighted problem.

    Examples
    --------
    The design closes a stable loop around the exact (unregularised) pitch axis:

    >>> import control as ct
    >>> from rotorlab import tune
    >>> K, gamma = tune.hinf_mixed_sensitivity("pitch")
    >>> G = tune.tuhh_axis_plant("pitch")                      # b -> [angle, rate], exact double integrator
    >>> cl = ct.feedback(K * G, 1)                             # r = 0: u = K [-angle, -rate] = -K G u
    >>> bool(np.all(np.real(cl.poles()) < 0)), bool(gamma > 0)
    (True, True)
    """
    G = tuhh_axis_plant(axis, pade_order=pade_order, regularize=regularize)
    P = tuhh_generalized_plant(G, weights)
    K, _, gamma, _ = ct.hinfsyn(P, 2, 1)
    return _drop_fast_modes(lti.as_ss(K)), float(gamma)


def _drop_fast_modes(K: ct.StateSpace, w_max: float = 1e5) -> ct.StateSpace:
    """Residualise controller poles faster than ``w_max`` rad/s (DC-matched singular perturbation).

    With a biproper ``W_K`` hinfsyn returns a near-static mode around -1e9 rad/s that only blows up the
    realisation's scaling; in an ordered real Schur basis the fast modes sit last and are residualised.
    """
    A = np.asarray(K.A, float)
    T, Z, sdim = sla.schur(A, output="real", sort=lambda re, im: abs(complex(re, im)) <= w_max)
    n_fast = A.shape[0] - sdim
    if n_fast == 0:
        return K
    Ks = ct.ss(T, Z.T @ K.B, K.C @ Z, K.D)
    return ct.modred(Ks, list(range(sdim, A.shape[0])), method="matchdc")


def glover_mcfarlane(G, W1=None, W2=None, gamma_factor: float = 1.1):
    """Glover-McFarlane H-inf loop-shaping design (normalised coprime factor robust stabilisation).

    Shaped plant ``Gs = W2 G W1``; ``gamma_min = sqrt(1 + rho(X Z))`` from the generalised control and filter
    AREs of ``Gs`` (scipy.linalg.solve_continuous_are; slycot's sb10id/sb10kd are not wrapped by
    python-control), ``epsilon_max = 1/gamma_min``; the central controller for ``gamma = gamma_factor *
    gamma_min`` (Skogestad & Postlethwaite, Multivariable Feedback Control, 2nd ed., eqs. 9.66-9.73, general
    ``D``) and the final controller ``K = W1 K_inf W2``.

    Parameters
    ----------
    G : continuous plant (p x m). W1 : pre-compensator (m x m), W2 : post-compensator (p x p); identity when None.
    gamma_factor : > 1, how far above the optimum to design (1.1 = 10 %, the usual choice).

    Returns
    -------
    K : control.StateSpace (m x p) for *negative* feedback ``u = -K y`` (the books' positive-feedback
        controller with its sign flipped).
    eps_max : float, the maximum normalised-coprime stability margin of ``Gs``.
    gamma : float, the design level (the achieved ``||[I; K_inf](I - Gs K_inf)^-1 [I, Gs]||_inf <= gamma``).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> G = ct.ss(ct.tf([1.0], [1, -1]))                         # unstable 1/(s - 1)
    >>> K, eps_max, gamma = tune.glover_mcfarlane(G)
    >>> cl = ct.feedback(G * K, 1)                               # u = -K y
    >>> bool(np.all(np.real(cl.poles()) < 0)), bool(0 < eps_max < 1)
    (True, True)
    """
    G = lti.as_ss(G)
    if lti.is_discrete(G):
        raise DataError("glover_mcfarlane works on continuous plants; convert with rotorlab.lti.d2c_zoh first")
    if not gamma_factor > 1.0:
        raise DataError(f"gamma_factor must exceed 1; got {gamma_factor}")
    p, m = G.noutputs, G.ninputs
    W1 = lti.as_ss(np.eye(m)) if W1 is None else lti.as_ss(W1)
    W2 = lti.as_ss(np.eye(p)) if W2 is None else lti.as_ss(W2)
    if (W1.ninputs, W1.noutputs) != (m, m) or (W2.ninputs, W2.noutputs) != (p, p):
        raise DataError(f"W1 must be {m}x{m} and W2 {p}x{p} for a {p}x{m} plant; got "
                        f"{W1.noutputs}x{W1.ninputs} and {W2.noutputs}x{W2.ninputs}")
    Gs = ct.series(W1, G, W2)
    A, B, C, D = (np.asarray(M, float) for M in (Gs.A, Gs.B, Gs.C, Gs.D))
    R = np.eye(p) + D @ D.T
    S = np.eye(m) + D.T @ D
    Si = np.linalg.inv(S)
    Ar = A - B @ Si @ D.T @ C
    Ri = np.linalg.inv(R)
    Z = sla.solve_continuous_are(Ar.T, C.T, B @ Si @ B.T, R)
    X = sla.solve_continuous_are(Ar, B, C.T @ Ri @ C, S)
    gmin = math.sqrt(1.0 + max(np.linalg.eigvals(X @ Z).real))
    gamma = gamma_factor * gmin
    F = -Si @ (D.T @ C + B.T @ X)
    L = (1.0 - gamma ** 2) * np.eye(A.shape[0]) + X @ Z
    LiT = np.linalg.inv(L.T)
    Ak = A + B @ F + gamma ** 2 * LiT @ Z @ C.T @ (C + D @ F)
    Bk = gamma ** 2 * LiT @ Z @ C.T
    Ck = B.T @ X
    Dk = -D.T
    Kinf = ct.ss(Ak, Bk, Ck, Dk)
    K = ct.series(W2, Kinf, W1)
    return -K, 1.0 / gmin, gamma
