"""Subspace identification: MOESP (Verhaegen & Dewilde 1992) and predictor-based PBSIDopt (Chiuso 2007).

Both return :class:`~rotorlab.ident.model.IdentifiedModel` with the input delay removed from ``sys`` and kept
in ``delay``: as in the published P2-A2 work, a known transport delay of ``d`` samples is taken out by pairing
``u[k - d]`` with ``y[k]`` before identification (a delay left in the data shows up as a spurious
non-minimum-phase zero) and put back by :meth:`IdentifiedModel.with_delay` / ``simulate``.
"""

from __future__ import annotations

import control as ct
import numpy as np
import scipy.linalg as sla

from rotorlab.errors import DataError

from ._data import block_hankel, check_int, check_io, hankel_gram, shift_delay
from .model import IdentifiedModel, lsim_fast, observability_sequence, state_regressors

__all__ = ["moesp", "pbsid"]


def moesp(u, y, order: int, horizon: int, dt: float = 1.0, delay: int = 0, feedthrough: bool = False,
          instruments: str = "io", noise_model: bool = True, ar_order: int = 20) -> IdentifiedModel:
    """MOESP subspace identification of ``x+ = A x + B u``, ``y = C x + D u + v``.

    Parameters
    ----------
    u, y : array_like, shape (N,) or (N, m) / (N, p)
        Input and output records sampled at ``dt``.
    order : int
        Model order n (``n <= (horizon - 1) p``).
    horizon : int
        Number of block rows ``s`` of the past and future Hankel matrices (the papers' ``p``).
    dt : float
        Sample time in s, stored in the model.
    delay : int
        Known input delay in samples, removed before identification and kept in the result.
    feedthrough : bool
        Estimate ``D`` (otherwise ``D = 0``, the right choice for sampled physical plants).
    instruments : {"io", "u"}
        Past inputs and outputs (PO-MOESP, also consistent with process noise) or past inputs only
        (PI-MOESP, the published variant, consistent for white output noise).
    noise_model : bool
        Also fit an innovation gain ``K`` to the output-error residual (two-stage: a long AR model of the
        residual gives the innovations, then ``K`` by least squares with ``A, C`` fixed). Without it
        ``K = 0`` (output-error form) and ``noise_cov`` is the residual covariance.
    ar_order : int
        Order of that residual AR model.

    Returns
    -------
    IdentifiedModel
        ``method = "pi-moesp"`` or ``"po-moesp"``; ``singular_values`` of the instrumented projection;
        ``extra["x0"]`` the initial state estimated with ``B, D``.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)

    >>> m = ident.moesp(u, y, order=2, horizon=10, dt=0.02, instruments="u")  # PI-MOESP, as published
    >>> m.method
    'pi-moesp'
    >>> print(round(float(ident.nugap(m.sys, G)), 4))                    # 0: the same model
    0.0
    """
    s = check_int(horizon, "horizon", 2)
    n = check_int(order, "order", 1)
    d = check_int(delay, "delay", 0)
    if instruments not in ("io", "u"):
        raise DataError(f"instruments must be 'io' (past inputs and outputs) or 'u' (past inputs); got {instruments!r}")
    u2, y2 = check_io(u, y, min_samples=1, what="moesp")
    m, p = u2.shape[1], y2.shape[1]
    if n > (s - 1) * p:
        raise DataError(
            f"order {n} is too large for horizon {s} with {p} output(s): need order <= (horizon - 1) * outputs "
            f"= {(s - 1) * p}; increase the horizon or lower the order"
        )
    u2, y2 = shift_delay(u2, y2, d)
    N = len(u2)
    cols = N - 2 * s + 1
    rows = 2 * s * m + s * p + (s * p if instruments == "io" else 0)
    if cols < 2 * rows:
        raise DataError(
            f"moesp with horizon {s} needs at least {2 * rows + 2 * s - 1 + d} samples "
            f"(twice as many Hankel columns as rows); got {N + d}: use a longer record or a smaller horizon"
        )
    L = _lq_factor(u2, y2, s, cols, instruments == "io")
    r1 = s * m
    r2 = rows - r1 - s * p
    L32 = L[r1 + r2:, r1: r1 + r2]
    Us, sv, _ = sla.svd(L32, full_matrices=False, check_finite=False)
    Un = Us[:, :n]
    C = Un[:p]
    A = sla.lstsq(Un[:-p], Un[p:], check_finite=False)[0]  # shift invariance
    B, D, x0 = _fit_bd_x0(A, C, u2, y2, feedthrough)
    y_sim = lsim_fast(A, B, C, D, u2, x0)
    resid = y2 - y_sim
    if noise_model:
        K, e = _residual_kalman_gain(A, C, resid, ar_order)
    else:
        K, e = np.zeros((n, p)), resid
    sys = ct.ss(A, B, C, D, dt)
    settings = dict(order=n, horizon=s, dt=dt, delay=d, feedthrough=feedthrough, instruments=instruments,
                    noise_model=noise_model)
    return IdentifiedModel(
        sys=sys, delay=d, method="po-moesp" if instruments == "io" else "pi-moesp", settings=settings, K=K,
        noise_cov=np.atleast_2d(np.cov(e.T)), singular_values=sv, extra={"x0": x0},
    )


def pbsid(u, y, order: int, past: int, future: int | None = None, dt: float = 1.0, delay: int = 0,
          feedthrough: bool = False) -> IdentifiedModel:
    """Predictor-based subspace identification (PBSIDopt, Chiuso 2007), consistent on closed-loop data.

    Identifies the innovation form ``x+ = A x + B u + K e``, ``y = C x + D u + e`` through its predictor
    ``x+ = (A - K C) x + (B - K D) u + K y``:

    1. VARX regression of ``y(k)`` on the past window ``z(k-past..k-1)``, ``z = [u; y]`` (and on ``u(k)``
       when ``feedthrough``): its coefficients are the predictor Markov parameters ``C Abar^i Btilde``.
    2. The block-triangular product "extended observability x extended controllability" is assembled
       from them (``future`` block rows, predictor powers beyond ``past`` taken as zero).
    3. Its SVD applied to the past data gives the state sequence; ``C, D`` then ``A, B, K`` follow by
       least squares with the innovations as an extra regressor.

    Parameters
    ----------
    u, y : array_like, shape (N,) or (N, m) / (N, p)
    order : int
        Model order n (``n <= future * p``).
    past : int
        Past window length (VARX order); must make ``Abar^past`` negligible, ``Abar = A - K C`` the
        predictor matrix. A too short window truncates the predictor and biases the low-frequency
        response. In closed loop with disturbances at the plant input the slowest predictor pole is the
        plant's slowest zero (the predictor inverts the noise model), not a plant pole: for the P2-A2 pitch
        model at 50 Hz it is 0.9435, so ``past = 20`` leaves ``0.31`` of it (about +3 % DC gain bias in a
        disturbed loop) and ``past = 50`` leaves ``0.055``. ``extra["predictor_decay"]`` reports
        ``max|eig(Abar)|^past`` of the identified model to check the choice.
    future : int, optional
        Future window (block rows of the observability matrix), ``order / p < future <= past``;
        defaults to ``past``.
    dt, delay, feedthrough
        As in :func:`moesp`.

    Returns
    -------
    IdentifiedModel
        ``method = "pbsid"``, ``K`` the innovation gain, ``noise_cov`` the innovation covariance,
        ``singular_values`` those the state was read from, ``extra["predictor_decay"]`` as above.

    Notes
    -----
    Consistent in closed loop (the future inputs are never projected out, unlike MOESP/N4SID), but the
    DC gain of a loop with a strong low-frequency disturbance is weakly informed by any data: its error
    shrinks with the record length (roughly as 1/N for the bias, 1/sqrt(N) for the spread), while the
    open-loop methods' bias does not.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)

    >>> m = ident.pbsid(u, y, order=2, past=20, future=10, dt=0.02)
    >>> print(np.round(np.sort_complex(np.log(m.sys.poles()) / 0.02), 3))  # continuous-time poles, rad/s
    [-2.791-3.675j -2.791+3.675j]
    """
    pst = check_int(past, "past", 1)
    fut = pst if future is None else check_int(future, "future", 1)
    n = check_int(order, "order", 1)
    d = check_int(delay, "delay", 0)
    if fut > pst:
        raise DataError(f"future window {fut} must not exceed the past window {pst}")
    u2, y2 = check_io(u, y, min_samples=1, what="pbsid")
    m, p = u2.shape[1], y2.shape[1]
    if n > fut * p:
        raise DataError(
            f"order {n} is too large for future window {fut} with {p} output(s): need order <= future * outputs "
            f"= {fut * p}; increase the future window or lower the order"
        )
    u2, y2 = shift_delay(u2, y2, d)
    N = len(u2)
    cols = N - pst
    nreg = pst * (m + p) + (m if feedthrough else 0)
    if cols < 3 * nreg:
        raise DataError(
            f"pbsid with past window {pst} needs at least {3 * nreg + pst + d} samples "
            f"(three times the {nreg} VARX regressors); got {N + d}: use a longer record or a shorter window"
        )
    q = m + p
    z = np.hstack([u2, y2])
    # VARX regressors z(k-past..k-1) (and u(k)) and target y(k) are all rows of the block Hankel matrix of z
    # with past + 1 block rows, so the normal equations come from its Gram matrix in O(N past) (see
    # _gram_factor); a dense QR of the N x past(m+p) regressor matrix costs O(N past^2) and would limit
    # the past window (which the slow predictor poles of closed-loop data need long) to about 20 at N = 7000.
    cur = pst * q
    u_now = cur + np.arange(m) if feedthrough else np.arange(0)
    idx = np.concatenate([np.arange(cur), u_now, cur + m + np.arange(p)])
    L = _gram_factor(z, pst + 1, cols, idx)
    # normal equations theta (L11 L11^T) = L21 L11^T, i.e. theta = L21 L11^-1
    theta = sla.solve_triangular(L[:nreg, :nreg], L[nreg:, :nreg].T, lower=True, trans="T",
                                 check_finite=False).T
    Xi = theta[:, :cur]
    GK = np.zeros((fut * p, cur))
    for i in range(fut):
        GK[i * p:(i + 1) * p, i * q:] = Xi[:, : (pst - i) * q]
    # The state is read from the row space of (Gamma K) Z. With Z Z^T = Lz Lz^T, (Gamma K) Lz has the same
    # left singular vectors and singular values as the (fut p x N) product, which is never formed.
    Lz = L[:cur, :cur]
    Us, sv, _ = sla.svd(GK @ Lz, full_matrices=False, check_finite=False)
    W = (Us[:, :n].T / np.sqrt(sv[:n])[:, None]) @ GK  # x(k) = W z(k-past..k-1)
    # X = W Z lag by lag: O(N past n) without the past(m+p) x N Hankel matrix
    Wl = W.reshape(n, pst, q)
    X = sum(Wl[:, j] @ z[j: j + cols].T for j in range(pst))  # n x cols, states at k = past..N-1
    Yk = y2[pst:].T
    Uk = u2[pst:].T
    if feedthrough:
        CD = _ls(np.vstack([X, Uk]), Yk)
        C, D = CD[:, :n], CD[:, n:]
    else:
        C = _ls(X, Yk)
        D = np.zeros((p, m))
    E = Yk - C @ X - D @ Uk
    ABK = _ls(np.vstack([X[:, :-1], Uk[:, :-1], E[:, :-1]]), X[:, 1:])
    A, B, K = ABK[:, :n], ABK[:, n:n + m], ABK[:, n + m:]
    sys = ct.ss(A, B, C, D, dt)
    settings = dict(order=n, past=pst, future=fut, dt=dt, delay=d, feedthrough=feedthrough)
    decay = float(np.max(np.abs(np.linalg.eigvals(A - K @ C)))) ** pst
    return IdentifiedModel(sys=sys, delay=d, method="pbsid", settings=settings, K=K,
                           noise_cov=np.atleast_2d(E @ E.T / E.shape[1]), singular_values=sv,
                           extra={"predictor_decay": decay})


def _ls(reg, target):
    """``argmin_T |target - T reg|_F`` for a few regressor rows and many samples (columns).

    R factor of the augmented matrix ``[reg; target]^T`` only (Q is never formed), then one triangular
    solve: several times cheaper than the SVD-based lstsq driver at this shape, and as accurate as QR.
    """
    k = reg.shape[0]
    R = np.linalg.qr(np.vstack([reg, target]).T, mode="r")
    return sla.solve_triangular(R[:k, :k], R[:k, k:], check_finite=False).T


def _lq_factor(u, y, s: int, cols: int, past_outputs: bool) -> np.ndarray:
    """Lower-triangular ``L`` of the LQ factorisation of ``[U_f; U_p; (Y_p;) Y_f]`` (Q is never needed)."""
    m, p = u.shape[1], y.shape[1]
    c = m + p
    t_f, t_p = np.arange(s, 2 * s), np.arange(s)
    sel = lambda times, chans: (times[:, None] * c + chans[None, :]).ravel()
    cu, cy = np.arange(m), np.arange(m, c)
    idx = [sel(t_f, cu), sel(t_p, cu)] + ([sel(t_p, cy)] if past_outputs else []) + [sel(t_f, cy)]
    return _gram_factor(np.hstack([u, y]), 2 * s, cols, np.concatenate(idx))


def _gram_factor(z: np.ndarray, rows: int, cols: int, idx: np.ndarray) -> np.ndarray:
    """Lower-triangular ``L`` with ``L L^T = M M^T``, ``M`` = rows ``idx`` of ``block_hankel(z, 0, rows, cols)``.

    First by Cholesky of the Gram matrix, built from the Hankel displacement structure in O(N rows) instead
    of the O(N rows^2) of a QR of ``M`` (``benchmarks/bench_ident.py`` times the two). Squaring the data
    halves the usable digits, so when the Gram matrix is near singular (noise-free or poorly excited data,
    where the small singular values matter) the dense QR is used instead.
    """
    G = hankel_gram(z, rows, cols)[np.ix_(idx, idx)]
    try:
        L = sla.cholesky(G, lower=True, check_finite=False)
        dg = np.abs(np.diag(L))
        if dg.min() > 1e-6 * dg.max():
            return L
    except sla.LinAlgError:
        pass
    M = block_hankel(z, 0, rows, cols)[idx]
    R = sla.qr(M.T, mode="r", overwrite_a=True, check_finite=False)[0]
    return R[: len(idx)].T


def _fit_bd_x0(A, C, u, y, feedthrough: bool):
    """Least-squares ``B``, ``D`` and ``x0`` given ``A``, ``C``: the output is linear in all three."""
    n, p, m, N = A.shape[0], C.shape[0], u.shape[1], len(u)
    cols = [state_regressors(A, C, u).reshape(N, p, n * m)]  # d y / d B[i, j]
    if feedthrough:
        Dreg = np.zeros((N, p, p, m))
        for i in range(p):
            Dreg[:, i, i, :] = u
        cols.append(Dreg.reshape(N, p, p * m))
    cols.append(observability_sequence(A, C, N))  # d y / d x0
    Phi = np.concatenate(cols, axis=2).reshape(N * p, -1)
    theta = _ls(Phi.T, y.ravel()[None, :])[0]
    B = theta[: n * m].reshape(n, m)
    k = n * m
    if feedthrough:
        D = theta[k: k + p * m].reshape(p, m)
        k += p * m
    else:
        D = np.zeros((p, m))
    return B, D, theta[k: k + n]


def _residual_kalman_gain(A, C, r, ar_order: int):
    """Innovation gain ``K`` for the output-error residual ``r = C (zI - A)^-1 K e + e`` (two-stage LS).

    A long AR model whitens ``r`` and so estimates the innovations ``e``; with ``e`` known the remaining
    term is linear in ``K``. This keeps MOESP's deterministic part and gives it the innovation form the
    bootstrap needs.
    """
    N, p = r.shape
    n = A.shape[0]
    ar = min(ar_order, max(1, N // 20))
    lagged = block_hankel(r, 0, ar, N - ar)  # r(k-ar..k-1)
    coef = _ls(lagged, r[ar:].T).T
    e = np.vstack([r[:ar], r[ar:] - lagged.T @ coef])
    Phi = state_regressors(A, C, e).reshape(N * p, n * p)
    k = _ls(Phi.T, (r - e).ravel()[None, :])[0]
    return k.reshape(n, p), e
