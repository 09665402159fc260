"""Anti-windup: the Riccati-based compensator of ref. 002 sec. 6 (Weston-Postlethwaite / Turner form) and PID
baselines (back-calculation, clamping), plus a small saturated-loop simulator to compare them.

Compensator (ref. 002 eq. 16), from the plant ``G = (A, B, C, D)``::

    x_aw' = (A + B F) x_aw + B u~          u~ = u - sat(u)
    u_d   = F x_aw                         (subtracted from the controller output: u = u_lin - u_d)
    y_d   = (C + D F) x_aw + D u~          (added to the measurement the controller sees: y + y_d)

i.e. ``u_d = (M - I) u~`` and ``y_d = G M u~`` with ``M = I + F (sI - A - BF)^-1 B``, so the controller
sees exactly the unconstrained linear loop ``y + y_d = G (u_lin + d)`` and saturation acts only through
the stable filter ``M``. ``F`` comes from a Riccati equation: ``F = -R^-1 B^T X`` with ``X`` the
stabilising solution of the plant's LQ ARE ``A^T X + X A - X B R^-1 B^T X + C^T Q C = 0`` (discrete: the
DARE and ``F = -(R + B^T X B)^-1 B^T X A``). This is the LQ member of the full-order family; ref. 002
cites the L2-gain-optimal Riccati/LMI construction of Turner & Postlethwaite, which needs an LMI solver we
do not ship, and the LQ choice already makes ``A + BF`` Hurwitz (the one hard requirement) with the
weights ``Q``, ``R`` trading how hard the compensator pulls the command back into the linear range.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import scipy.linalg as sla

from rotorlab import lti
from rotorlab.errors import DataError

__all__ = ["riccati_antiwindup", "pid_backcalculation", "simulate_saturated_loop"]


def riccati_antiwindup(G, q: float = 1.0, r: float = 1.0) -> ct.StateSpace:
    """Riccati-based full-order anti-windup compensator ``Theta`` for plant ``G`` (continuous or discrete).

    Parameters
    ----------
    G : plant (p outputs, m inputs) with the states the controller's plant model would have.
    q, r : output and input weights of the ARE (scalars: ``Q = q I_p``, ``R = r I_m``).

    Returns
    -------
    control.StateSpace
        inputs ``u_tilde[0..m-1]`` (``u - sat(u)``), outputs ``u_d[0..m-1]`` then ``y_d[0..p-1]``; same dt as G.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import tune
    >>> Theta = tune.riccati_antiwindup(ct.ss(ct.tf([1.0], [1, 0, 0])))     # a double integrator
    >>> Theta.ninputs, Theta.noutputs, bool(np.all(np.real(Theta.poles()) < 0))
    (1, 2, True)
    """
    G = lti.as_ss(G)
    A, B, C, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
    if not all(np.all(np.isfinite(M)) for M in (A, B, C, D)):
        raise DataError("the plant model contains NaN or inf entries")
    if not (q > 0 and r > 0):
        raise DataError(f"Riccati weights must be positive; got q={q}, r={r}")
    p, m = D.shape
    Q = q * C.T @ C
    R = r * np.eye(m)
    if lti.is_discrete(G):
        X = sla.solve_discrete_are(A, B, Q, R)
        F = -np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    else:
        X = sla.solve_continuous_are(A, B, Q, R)
        F = -np.linalg.solve(R, B.T @ X)
    Acl = A + B @ F
    theta = ct.ss(Acl, B, np.vstack([F, C + D @ F]), np.vstack([np.zeros((m, m)), D]), G.dt,
                  inputs=[f"u_tilde[{i}]" for i in range(m)],
                  outputs=[f"u_d[{i}]" for i in range(m)] + [f"y_d[{i}]" for i in range(p)])
    if not lti.is_stable(theta):
        raise DataError("A + B F is not stable: the plant is not stabilisable/detectable through C for the ARE")
    return theta


def pid_backcalculation(kp: float, ki: float, kd: float = 0.0, tf: float = 0.0, tt_s: float | None = None,
                        n_err: int = 1) -> ct.StateSpace:
    """PID with back-calculation anti-windup: ``x_i' = ki e - u~ / Tt``.

    ``n_err = 1``: ``u = kp e + x_i + kd s/(tf s + 1) e``. ``n_err = 2``: the modified PID of ref. 002 on
    ``[r - angle, -rate]``: ``u = kp e1 + x_i + kd e2`` (D from the measured rate; ``tf`` unused).
    Default tracking time ``Tt = sqrt(Ti Td)`` (Astrom & Hagglund), or ``Ti/2`` without D.

    Returns a continuous StateSpace with inputs ``e[0..n_err-1]`` and ``u_tilde``, output ``u``.

    Parameters
    ----------
    kp, ki, kd : float
        PID gains.
    tf : float
        Derivative filter time constant, s.
    tt_s : float, optional
        Tracking time constant of the back-calculation, s.
    n_err : {1, 2}
        One error input, or the modified PID's ``[r - angle, -rate]``.

    Returns
    -------
    StateSpace
        Continuous, inputs ``[error(s), u~]`` with ``u~ = u - sat(u)``, output ``u``.

    Examples
    --------
    >>> from rotorlab import tune
    >>> K = tune.pid_backcalculation(kp=1.0, ki=2.0)           # PI: tracking time Ti / 2 = 0.25 s
    >>> K.ninputs, K.noutputs                                  # [e, u~] -> u
    (2, 1)
    """
    if ki <= 0:
        raise DataError(f"back-calculation needs integral action; got ki={ki}")
    ti = kp / ki if kp else 1.0 / ki
    if tt_s is None:
        tt_s = math.sqrt(ti * kd / kp) if (kd and kp) else ti / 2.0
    if n_err == 2:
        A, B = [[0.0]], [[ki, 0.0, -1.0 / tt_s]]
        C, D = [[1.0]], [[kp, kd, 0.0]]
    elif n_err == 1:
        if kd:
            # states: integral, derivative filter x_f with D term kd/tf (e - x_f)
            A = [[0.0, 0.0], [0.0, -1.0 / tf]]
            B = [[ki, -1.0 / tt_s], [1.0 / tf, 0.0]]
            C = [[1.0, -kd / tf]]
            D = [[kp + kd / tf, 0.0]]
        else:
            A, B, C, D = [[0.0]], [[ki, -1.0 / tt_s]], [[1.0]], [[kp, 0.0]]
    else:
        raise DataError(f"n_err must be 1 or 2; got {n_err}")
    names = [f"e[{i}]" for i in range(n_err)] + ["u_tilde"]
    return ct.ss(A, B, C, D, inputs=names, outputs=["u"])


def _disc(sys, dt):
    sys = lti.as_ss(sys)
    if lti.is_discrete(sys):
        if not math.isclose(float(sys.dt), dt):
            raise DataError(f"discrete model has dt={sys.dt} s but the simulation runs at {dt} s")
        return sys
    return lti.c2d_zoh(sys, dt)


def simulate_saturated_loop(G, K, t_final_s: float, dt: float, r=0.0, d=0.0, u_max: float = math.inf,
                            delay_s: float = 0.0, aw=None) -> dict:
    """Discrete-time simulation of ``y = G(sat(u) + d)`` with exact input delay, controller ``K`` and
    optional anti-windup.

    Parameters
    ----------
    G : plant, 1 input, p outputs (continuous: ZOH at ``dt``; or discrete with this dt).
    K : controller on the error vector ``e = r_vec - y_seen`` (``r_vec = (r, 0, ..)``: the reference
        applies to the first output), output ``u_lin``. A controller with ``p + 1`` inputs takes
        ``u_tilde`` as last input (back-calculation, :func:`pid_backcalculation`).
    t_final_s, dt : horizon and step, s.
    r, d : reference and input disturbance: scalars (steps at t = 0) or arrays over the time grid.
    u_max : saturation ``|sat(u)| <= u_max`` (command units).
    delay_s : exact input delay (multiple of dt).
    aw : None; ``"clamp"`` (conditional integration: controller states frozen while saturated and the
        unfrozen update would drive ``u`` further into saturation); or a compensator from
        :func:`riccati_antiwindup` (continuous ones are ZOH-discretised).

    Returns
    -------
    dict with ``t`` (nt,), ``y`` (nt, p), ``u`` (command before saturation), ``u_sat``, ``u_lin`` (the
    controller output) and ``y_d`` (nt, p) (the compensator's measurement correction; zeros without one).

    Examples
    --------
    A PI loop on ``1/(s + 1)`` whose command saturates at 1.5 on a unit step: clamping keeps the overshoot down.

    >>> import control as ct
    >>> from rotorlab import tune
    >>> G, K = ct.tf([1.0], [1, 1]), ct.ss(ct.tf([4.0, 8.0], [1, 0]))       # kp 4, ki 8
    >>> plain = tune.simulate_saturated_loop(G, K, 6.0, 0.01, r=1.0, u_max=1.5)
    >>> clamp = tune.simulate_saturated_loop(G, K, 6.0, 0.01, r=1.0, u_max=1.5, aw="clamp")
    >>> bool(clamp["y"][:, 0].max() < plain["y"][:, 0].max()), round(float(clamp["y"][-1, 0]), 3)
    (True, 1.0)
    """
    Gd, Kd = _disc(G, dt), _disc(K, dt)
    p = Gd.noutputs
    if Gd.ninputs != 1:
        raise DataError(f"simulate_saturated_loop handles single-input plants; got {Gd.ninputs} inputs")
    backcalc = Kd.ninputs == p + 1
    if Kd.ninputs not in (p, p + 1) or Kd.noutputs != 1:
        raise DataError(f"controller is {Kd.noutputs}x{Kd.ninputs}; expected 1x{p} (or 1x{p + 1} with u_tilde)")
    nd = delay_s / dt
    if abs(nd - round(nd)) > 1e-6:
        raise DataError(f"delay {delay_s} s is not a multiple of dt={dt} s")
    nd = int(round(nd))
    t = np.arange(0.0, t_final_s + 1e-12, dt)
    nt = t.size
    try:
        r = np.broadcast_to(np.asarray(r, float), (nt,))
        d = np.broadcast_to(np.asarray(d, float), (nt,))
    except ValueError:
        raise DataError(f"r and d must be scalars or arrays of the {nt} time steps "
                        f"(got shapes {np.shape(r)} and {np.shape(d)})") from None
    Ag, Bg, Cg, Dg = (np.asarray(M, float) for M in (Gd.A, Gd.B, Gd.C, Gd.D))
    Ak, Bk, Ck, Dk = (np.asarray(M, float) for M in (Kd.A, Kd.B, Kd.C, Kd.D))
    if np.any(Dg):
        raise DataError("the plant must be strictly proper (no direct feedthrough) for this simulator")
    if backcalc and np.any(Dk[:, p:]):
        raise DataError("the controller's u_tilde input must not feed through directly")
    theta = None
    if aw is not None and not isinstance(aw, str):
        Th = _disc(aw, dt)
        if Th.ninputs != 1 or Th.noutputs != 1 + p:
            raise DataError(f"anti-windup compensator must have 1 input and {1 + p} outputs (u_d, y_d); "
                            f"got {Th.ninputs} and {Th.noutputs}")
        theta = tuple(np.asarray(M, float) for M in (Th.A, Th.B, Th.C, Th.D))
        if np.any(theta[3]):
            raise DataError("the compensator must be strictly proper (it is, for a strictly proper plant)")
        xa = np.zeros(theta[0].shape[0])
    elif aw not in (None, "clamp"):
        raise DataError(f"aw must be None, 'clamp' or a StateSpace compensator; got {aw!r}")
    xg = np.zeros(Ag.shape[0])
    xk = np.zeros(Ak.shape[0])
    past = np.zeros(nd)  # saturated commands still travelling through the input delay, oldest first
    Y = np.empty((nt, p))
    U = np.empty(nt)
    Us = np.empty(nt)
    Ul = np.empty(nt)
    Yd = np.zeros((nt, p))
    nk = p if not backcalc else p + 1
    clamp = isinstance(aw, str) and aw == "clamp"
    for k in range(nt):
        y = Cg @ xg
        if theta is not None:
            out = theta[2] @ xa
            ud, yd = out[0], out[1:]
        else:
            ud, yd = 0.0, 0.0
        ek = np.zeros(nk)
        ek[:p] = -(y + yd)
        ek[0] += r[k]
        ul = float((Ck @ xk + Dk @ ek)[0])  # the u_tilde column of D is zero (checked above)
        u = ul - ud
        us = min(max(u, -u_max), u_max)
        ut = u - us
        if backcalc:
            ek[p] = ut
        xk_new = Ak @ xk + Bk @ ek
        if not (clamp and ut != 0.0 and float((Ck @ (xk_new - xk))[0]) * ut > 0):
            xk = xk_new
        if theta is not None:
            xa = theta[0] @ xa + theta[1][:, 0] * ut
        if nd:
            v = past[0]
            past[:-1] = past[1:]
            past[-1] = us
        else:
            v = us
        xg = Ag @ xg + Bg[:, 0] * (v + d[k])
        Y[k], U[k], Us[k], Ul[k], Yd[k] = y, u, us, ul, yd
    return {"t": t, "y": Y, "u": U, "u_sat": Us, "u_lin": Ul, "y_d": Yd}
