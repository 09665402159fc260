"""Shared LTI math: the one place for frequency responses, exact H-inf norms, delays, ZOH inversion and
the discrete controller forms that both the flight software and the tuner must agree on.

Everything takes and returns python-control objects (``control.StateSpace`` / ``TransferFunction``);
``dt = 0`` means continuous time, ``dt > 0`` discrete with that sample time in seconds.
"""

from __future__ import annotations

import copyreg
import warnings

import control as ct
import numpy as np
import scipy.linalg as sla
import slycot

__all__ = [
    "as_ss",
    "is_discrete",
    "freqresp",
    "hinfnorm",
    "hinfnorm_stable",
    "spectral_abscissa",
    "is_stable",
    "delay_ss",
    "with_io_delay",
    "d2c_zoh",
    "negative_real_poles",
    "c2d_zoh",
    "pid_tf",
    "pid2_ss",
    "s_plane",
    "dc_gain",
]


D2C_TOL = 1e-6  # relative error of expm(logm(M)) against M that d2c_zoh accepts; well-posed plants give 1e-14


def _rebuild_ss(A, B, C, D, dt, inputs, outputs, states, name):
    return ct.ss(A, B, C, D, dt, inputs=inputs, outputs=outputs, states=states, name=name)


def _reduce_ss(sys):
    return _rebuild_ss, (np.asarray(sys.A), np.asarray(sys.B), np.asarray(sys.C), np.asarray(sys.D), sys.dt,
                         list(sys.input_labels), list(sys.output_labels), list(sys.state_labels), sys.name)


# python-control's StateSpace holds a lambda and does not pickle; the executors send models to worker processes
# (local pools and Dask), so a StateSpace pickles as its matrices, sample time and signal names
copyreg.pickle(ct.StateSpace, _reduce_ss)


def as_ss(sys) -> ct.StateSpace:
    """Return ``sys`` as a ``control.StateSpace`` (a static gain becomes a 0-state system)."""
    if isinstance(sys, ct.StateSpace):
        return sys
    if isinstance(sys, ct.TransferFunction):
        return ct.tf2ss(sys)
    d = np.atleast_2d(np.asarray(sys, dtype=float))
    return ct.ss(np.zeros((0, 0)), np.zeros((0, d.shape[1])), np.zeros((d.shape[0], 0)), d)


def is_discrete(sys) -> bool:
    dt = sys.dt
    return dt is True or (dt is not None and dt > 0)


def freqresp(sys, omega_rad_s) -> np.ndarray:
    """Complex frequency response, shape ``(len(omega), p, m)``.

    Discrete systems are evaluated at ``z = exp(j omega dt)``; ``omega`` is in rad/s for both.
    """
    sys = as_ss(sys)
    w = np.atleast_1d(np.asarray(omega_rad_s, dtype=float))
    if is_discrete(sys):
        pts = np.exp(1j * w * float(sys.dt))
    else:
        pts = 1j * w
    A, B, C, D = (np.asarray(M, dtype=complex) for M in (sys.A, sys.B, sys.C, sys.D))
    n = A.shape[0]
    out = np.empty((w.size, D.shape[0], D.shape[1]), dtype=complex)
    if n == 0:
        out[:] = D
        return out
    # Hessenberg reduction once, then one solve per point: this is how SLICOT's tb05ad does it and it is
    # several times faster than a dense solve per frequency for the 10-60 state loops we evaluate.
    H, Q = sla.hessenberg(A, calc_q=True)
    Bq = Q.conj().T @ B
    Cq = C @ Q
    eye = np.eye(n)
    for k, p in enumerate(pts):
        out[k] = Cq @ np.linalg.solve(p * eye - H, Bq) + D
    return out


def hinfnorm(sys, tols=(1e-10, 1e-8)) -> tuple[float, float]:
    """Exact H-inf norm and peak frequency (rad/s) of a stable system, by SLICOT ab13dd.

    ab13dd returns a lower bound that meets its tolerance; at a tight tolerance (1e-10) it occasionally
    stops early (e.g. at the high-frequency gain ``|D|`` of a 2-state system whose peak is 14 % higher),
    at 1e-8 it does not. Both results are lower bounds of the true norm, so the larger is kept. ``tols``
    chooses the tolerances run (an optimiser's inner loop runs 1e-8 alone, at half the cost).
    Returns ``(inf, nan)`` for an unstable system, since its H-inf norm is not defined.
    """
    sys = as_ss(sys)
    if not is_stable(sys):
        return float("inf"), float("nan")
    return hinfnorm_stable(*(np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D)),
                           float(sys.dt) if is_discrete(sys) else 0.0, tols)


def hinfnorm_stable(A, B, C, D, dt=0.0, tols=(1e-10, 1e-8)) -> tuple[float, float]:
    """:func:`hinfnorm` of the stable system ``(A, B, C, D)`` (sample time ``dt`` s, 0 for continuous) from
    its matrices, without building a StateSpace or checking stability: for optimisers that have already
    checked stability from the same closed-loop eigenvalues and evaluate the norm thousands of times."""
    n = A.shape[0]
    if n == 0:
        return float(np.linalg.norm(D, 2)), 0.0
    dico = "D" if dt else "C"
    p, m = D.shape
    E = np.eye(n)
    jobd = "D" if np.any(D) else "Z"
    best = (-1.0, 0.0)
    for tol in tols:
        gpeak, fpeak = slycot.ab13dd(dico, "I", "S", jobd, n, m, p, A, E, B, C, D, tol)
        if gpeak > best[0]:
            best = (gpeak, fpeak)
    gpeak, fpeak = best
    # discrete peaks come back as an angle in rad/sample
    wpk = fpeak / float(dt) if dico == "D" else fpeak
    return float(gpeak), float(wpk)


def spectral_abscissa(sys) -> float:
    """Largest real part of the poles (continuous) or largest pole modulus minus one (discrete).

    Negative means asymptotically stable in both cases.
    """
    sys = as_ss(sys)
    if sys.nstates == 0:
        return -np.inf
    ev = np.linalg.eigvals(np.asarray(sys.A, dtype=float))
    if is_discrete(sys):
        return float(np.max(np.abs(ev)) - 1.0)
    return float(np.max(ev.real))


def is_stable(sys, margin: float = 0.0) -> bool:
    return spectral_abscissa(sys) < -margin


def delay_ss(nsamples: int, dt: float, width: int = 1) -> ct.StateSpace:
    """Pure delay ``z^-nsamples`` on ``width`` channels, as a discrete StateSpace."""
    if nsamples < 0 or int(nsamples) != nsamples:
        raise ValueError(f"delay must be a non-negative whole number of samples, got {nsamples}")
    nsamples = int(nsamples)
    if nsamples == 0:
        return ct.ss([], [], [], np.eye(width), dt)
    n = nsamples * width
    A = np.zeros((n, n))
    A[width:, :-width] = np.eye(n - width)
    B = np.zeros((n, width))
    B[:width] = np.eye(width)
    C = np.zeros((width, n))
    C[:, -width:] = np.eye(width)
    return ct.ss(A, B, C, np.zeros((width, width)), dt)


def with_io_delay(sys, delay_s: float, pade_order: int = 5, where: str = "input") -> ct.StateSpace:
    """Append a transport delay on every input (or output) of ``sys``.

    Discrete: an exact ``z^-k`` shift register (``delay_s`` must be a multiple of ``dt``). Continuous:
    a Pade approximation of ``pade_order``.
    """
    sys = as_ss(sys)
    if delay_s == 0:
        return sys
    width = sys.ninputs if where == "input" else sys.noutputs
    if is_discrete(sys):
        k = delay_s / float(sys.dt)
        if abs(k - round(k)) > 1e-6:
            raise ValueError(
                f"delay {delay_s} s is not a multiple of the sample time {sys.dt} s (got {k:.4f} samples)"
            )
        dl = delay_ss(int(round(k)), float(sys.dt), width)
    else:
        num, den = ct.pade(delay_s, pade_order)
        dl = ct.append(*[ct.tf2ss(ct.tf(num, den))] * width) if width > 1 else ct.tf2ss(ct.tf(num, den))
    return ct.series(dl, sys) if where == "input" else ct.series(sys, dl)


def c2d_zoh(sys, dt: float) -> ct.StateSpace:
    """Zero-order-hold discretisation (thin wrapper so every caller uses the same method)."""
    return ct.c2d(as_ss(sys), dt, method="zoh")


def negative_real_poles(sysd) -> np.ndarray:
    """Poles of a discrete model on the non-positive real axis: a model with any has no ZOH continuous
    equivalent (see :func:`d2c_zoh`)."""
    ev = np.linalg.eigvals(np.asarray(as_ss(sysd).A, dtype=float))
    return ev[(np.abs(ev.imag) < 1e-9) & (ev.real <= 0)].real


def s_plane(roots, dt: float = 0.0) -> np.ndarray:
    """Roots in rad/s: continuous roots as they are, discrete ones mapped by ``s = ln(z) / dt`` (exact for the
    poles of a ZOH discretisation; a root at z = 0, a pure delay, maps to -inf)."""
    r = np.asarray(roots, dtype=complex)
    if not dt:
        return r
    with np.errstate(divide="ignore"):
        return np.log(r) / dt


def dc_gain(sys) -> np.ndarray:
    """Steady-state gain matrix (outputs x inputs): G(0) continuous, G(1) discrete; inf where a pole sits there."""
    sys = as_ss(sys)
    try:
        return np.real_if_close(freqresp(sys, [0.0])[0])
    except np.linalg.LinAlgError:
        return np.full((sys.noutputs, sys.ninputs), np.inf)


def d2c_zoh(sysd) -> ct.StateSpace:
    """Inverse of the zero-order-hold discretisation, through the matrix logarithm of the augmented
    ``[[A, B], [0, I]]`` matrix (exact when A has no eigenvalues on the negative real axis)."""
    sysd = as_ss(sysd)
    if not is_discrete(sysd):
        raise ValueError("d2c_zoh needs a discrete system (dt > 0)")
    dt = float(sysd.dt)
    n, m = sysd.nstates, sysd.ninputs
    A, B = np.asarray(sysd.A, float), np.asarray(sysd.B, float)
    bad = negative_real_poles(sysd)
    if bad.size:
        raise ValueError(
            f"d2c_zoh: the model has poles on the non-positive real axis {bad}; "
            "it has no continuous-time ZOH equivalent (try a different order or remove the delay first)"
        )
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    M[n:, n:] = np.eye(m)
    with warnings.catch_warnings():
        # scipy warns on its own error estimate (about 2e-13 on the twins' plants); the round trip below checks
        warnings.simplefilter("ignore", RuntimeWarning)
        L = sla.logm(M)
    L = np.real_if_close(L, tol=1e6)
    if np.iscomplexobj(L):
        L = L.real
    err = float(np.linalg.norm(sla.expm(L) - M) / np.linalg.norm(M))
    if err > D2C_TOL:
        raise ValueError(f"d2c_zoh: the matrix logarithm is inaccurate (relative round-trip error {err:.2g})")
    L = L / dt
    return ct.ss(L[:n, :n], L[:n, n:], sysd.C, sysd.D)


def pid_tf(kp: float, ki: float = 0.0, kd: float = 0.0, tf: float = 0.0, dt: float = 0.0):
    """Parallel PID with filtered derivative, ``C = kp + ki I(s) + kd / (tf + I(s))``.

    ``I(s) = 1/s`` in continuous time; in discrete time the forward-Euler integrator ``I(z) = dt/(z-1)``
    for both the integral and the derivative filter (MATLAB's ``pid(..., 'IFormula','ForwardEuler',
    'DFormula','ForwardEuler')``, the form the published gains were tuned in). Discrete derivative
    filters need ``tf > dt/2`` to be stable.
    """
    if dt and dt > 0:
        integ = ct.tf([dt], [1, -1], dt)
        C = ct.tf([kp], [1], dt)
        if ki:
            C = C + ki * integ
        if kd:
            # kd / (tf + dt/(z-1)) = kd (z-1) / (tf (z-1) + dt)
            C = C + ct.tf([kd, -kd], [tf, dt - tf], dt)
        return ct.minreal(C, verbose=False) if (ki or kd) else C
    s = ct.tf([1, 0], [1])
    C = ct.tf([kp], [1])
    if ki:
        C = C + ki / s
    if kd:
        C = C + ct.tf([kd, 0], [tf, 1])
    return C


def pid2_ss(kp: float, ki: float = 0.0, kd: float = 0.0, tf: float = 0.0, b: float = 1.0, c: float = 1.0,
            dt: float = 0.0) -> ct.StateSpace:
    """Two-degree-of-freedom PID as a 2-input (r, y), 1-output StateSpace:

    ``u = kp (b r - y) + ki I (r - y) + kd / (tf + I) (c r - y)``, with ``I`` as in :func:`pid_tf`.
    """
    P = ct.ss([], [], [], [[kp * b, -kp]], dt)
    parts = [P]
    if ki:
        Ii = as_ss(pid_tf(0.0, ki, 0.0, 0.0, dt))
        parts.append(ct.series(ct.ss([], [], [], [[1.0, -1.0]], dt), Ii))
    if kd:
        Dd = as_ss(pid_tf(0.0, 0.0, kd, tf, dt))
        parts.append(ct.series(ct.ss([], [], [], [[c, -1.0]], dt), Dd))
    out = parts[0]
    for p in parts[1:]:
        out = ct.parallel(out, p)
    return out


def c2d_zoh_delay(sys, dt: float, delay_s: float = 0.0) -> ct.StateSpace:
    """Exact zero-order-hold discretisation of ``sys`` with an input transport delay ``delay_s`` (s).

    The delay need not be a multiple of ``dt``: with ``delay_s = (d + f) dt``, ``0 <= f < 1``, the held input
    switches inside the sample interval, giving ``x[k+1] = Phi x[k] + G1 u[k-d-1] + G0 u[k-d]`` with
    ``G0 = int_0^{(1-f)dt} e^{A s} ds B`` and ``G1 = e^{A(1-f)dt} int_0^{f dt} e^{A s} ds B`` (the modified
    z-transform; Franklin, Powell & Workman, Digital Control, sec. 4.3.4). python-control has no fractional
    input delay, hence this function.

    State order: the plant states first (so an initial state of ``sys`` maps onto the first ``n`` states),
    then ``u[k-d-1]`` (only when ``f > 0``), then the ``d``-sample input shift register.

    ``delay_s`` may be a sequence, one delay per input of ``sys``: one input ``u`` drives every input of ``sys``,
    input ``i`` after ``delay_s[i]`` (several paths of one command with their own transport delays); the result
    has the one input, the plant states first, then one line of ``u``'s past samples that every path taps.

    Examples
    --------
    >>> G = c2d_zoh_delay(ct.ss(ct.tf([1.0], [0.1, 1.0])), 0.01, 0.025)
    >>> G.nstates  # the lag, u[k-3] for the half sample, and the two-sample shift register
    4
    >>> H = c2d_zoh_delay(ct.ss([[-10.0]], [[10.0, 10.0]], [[1.0]], [[0.0, 0.0]]), 0.01, [0.0, 0.02])
    >>> H.nstates, H.ninputs  # one lag, the two-sample line of u that the second path reads
    (3, 1)
    """
    sys = as_ss(sys)
    if is_discrete(sys):
        raise ValueError("c2d_zoh_delay needs a continuous system")
    if np.ndim(delay_s):
        return _c2d_zoh_taps(sys, dt, [float(d) for d in delay_s])
    if delay_s < 0:
        raise ValueError(f"delay must be non-negative, got {delay_s} s")
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    n, m = B.shape
    k = delay_s / dt
    d = int(np.floor(k + 1e-9))
    f = k - d
    if f < 1e-9:
        f = 0.0

    def phi_gamma(tau):
        M = np.zeros((n + m, n + m))
        M[:n, :n] = A
        M[:n, n:] = B
        E = sla.expm(M * tau)
        return E[:n, :n], E[:n, n:]

    Phi, _ = phi_gamma(dt)
    if f == 0.0:
        Ah, Bh, Ch, Dh = Phi, phi_gamma(dt)[1], C, D
    else:
        Pa, G0 = phi_gamma((1.0 - f) * dt)
        _, Gf = phi_gamma(f * dt)
        G1 = Pa @ Gf
        Ah = np.block([[Phi, G1], [np.zeros((m, n + m))]])
        Bh = np.vstack([G0, np.eye(m)])
        Ch = np.hstack([C, D])
        Dh = np.zeros_like(D)
    if d == 0:
        return ct.ss(Ah, Bh, Ch, Dh, dt)
    line = delay_ss(d, dt, m)
    Al, Bl, Cl = (np.asarray(M, dtype=float) for M in (line.A, line.B, line.C))
    nh, nl = Ah.shape[0], Al.shape[0]
    Acl = np.block([[Ah, Bh @ Cl], [np.zeros((nl, nh)), Al]])
    Bcl = np.vstack([np.zeros((nh, m)), Bl])
    Ccl = np.hstack([Ch, Dh @ Cl])
    return ct.ss(Acl, Bcl, Ccl, np.zeros_like(D), dt)


def _c2d_zoh_taps(sys: ct.StateSpace, dt: float, delays_s) -> ct.StateSpace:
    """:func:`c2d_zoh_delay` of ``sys`` whose inputs are driven by one input, input ``i`` after ``delays_s[i]``:
    one tapped delay line of the input's past samples, each input column reading its taps (the fewest states)."""
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    n, m = B.shape
    if len(delays_s) != m:
        raise ValueError(f"{len(delays_s)} delays for a system with {m} inputs")
    if min(delays_s) < 0:
        raise ValueError(f"delays must be non-negative, got {list(delays_s)} s")

    def phi_gamma(b, tau):
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = A
        M[:n, n:] = b
        E = sla.expm(M * tau)
        return E[:n, :n], E[:n, n:]

    taps = []  # (tap j: the input sample u[k - j], its column into x, its column into y)
    for i, delay in enumerate(delays_s):
        b, dcol = B[:, [i]], D[:, [i]]
        k = delay / dt
        d = int(np.floor(k + 1e-9))
        f = k - d if k - d >= 1e-9 else 0.0
        if f == 0.0:
            taps += [(d, phi_gamma(b, dt)[1], dcol)]
        else:
            Pa, G0 = phi_gamma(b, (1.0 - f) * dt)
            taps += [(d, G0, np.zeros_like(dcol)), (d + 1, Pa @ phi_gamma(b, f * dt)[1], dcol)]
    L = max(j for j, *_ in taps)
    Ad = np.zeros((n + L, n + L))
    Ad[:n, :n] = sla.expm(A * dt)
    Bd = np.zeros((n + L, 1))
    Cd = np.zeros((C.shape[0], n + L))
    Cd[:, :n] = C
    Dd = np.zeros((C.shape[0], 1))
    if L:
        Bd[n, 0] = 1.0  # u[k] -> u[k-1]
        Ad[n + 1:, n:-1] = np.eye(L - 1)  # u[k-j] -> u[k-j-1]
    for j, g, dcol in taps:
        if j == 0:
            Bd[:n] += g
            Dd += dcol
        else:
            Ad[:n, [n + j - 1]] += g
            Cd[:, [n + j - 1]] += dcol
    return ct.ss(Ad, Bd, Cd, Dd, dt)
