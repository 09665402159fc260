"""Order and horizon selection by cross-validation VAF, as in the published P2-A2 study."""

from __future__ import annotations

from itertools import product

import numpy as np
from tqdm import tqdm

from rotorlab.errors import DataError

from .methods import METHODS
from .metrics import simulate, vaf

__all__ = ["select_order", "SUBSPACE_METHODS"]

SUBSPACE_METHODS = ("pi-moesp", "pbsid")  # the methods whose order and horizons select_order searches


def select_order(u_id, y_id, u_cv, y_cv, method: str = "pi-moesp", orders=range(1, 7), horizons=(10, 20, 40),
                 delay: int = 0, dt: float = 1.0, progress: bool = False, accept=None):
    """Grid search of model order and horizon by VAF on a cross-validation record.

    Parameters
    ----------
    u_id, y_id : array_like
        Identification record.
    u_cv, y_cv : array_like
        Cross-validation record (not used to fit; its initial state is estimated).
    method : {"pi-moesp", "pbsid"}
        A subspace method of :data:`rotorlab.ident.methods.METHODS`.
    orders : iterable of int
    horizons : iterable
        PI-MOESP: block rows ``s``. PBSID: ``(past, future)`` pairs, or ints meaning ``past = future``.
    delay, dt
        Passed to the identification function (samples, s).
    accept : callable, optional
        ``accept(model) -> bool``: models it rejects are scored and listed (``accepted: False``) but never
        chosen, e.g. models without a continuous-time ZOH equivalent when the model will be analysed in
        continuous time.

    Returns
    -------
    best : IdentifiedModel
        The model with the highest mean cross-validation VAF.
    table : list of dict
        One row per tried setting: ``settings`` and ``vaf_cv`` (percent per output, mean); settings that
        are invalid for the data (order too high for the horizon) are skipped.

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)
    >>> y = y + 0.2 * np.random.default_rng(1).standard_normal(len(y))  # gyro noise, deg/s

    >>> best, table = ident.select_order(u[:2000], y[:2000], u[2000:], y[2000:], method="pbsid", orders=[1, 2, 3],
    ...                                  horizons=[10], dt=0.02)
    >>> best.sys.nstates, len(table)
    (2, 3)
    """
    if method not in SUBSPACE_METHODS:
        raise DataError(f"method must be one of {', '.join(SUBSPACE_METHODS)}; got {method!r}")
    fit = METHODS[method].fit
    pairs = list(product(list(orders), list(horizons)))
    grid = tqdm(pairs, desc=f"select_order {method}") if progress else pairs
    table, best, best_vaf = [], None, -np.inf
    for n, h in grid:
        try:
            if method == "pi-moesp":
                m = fit(u_id, y_id, dt=dt, delay=delay, order=n, horizon=h)
            else:
                past, future = (h, h) if np.isscalar(h) else h
                m = fit(u_id, y_id, dt=dt, delay=delay, order=n, past=past, future=future)
        except DataError:
            continue
        v = vaf(y_cv, simulate(m, u_cv, x0="estimate", y=y_cv))
        ok = accept is None or bool(accept(m))
        table.append({"settings": dict(m.settings), "vaf_cv": v, "vaf_cv_mean": float(np.mean(v)), "accepted": ok})
        if ok and np.mean(v) > best_vaf:
            best, best_vaf = m, float(np.mean(v))
    if best is None:
        tried = ", ".join(f"order {r['settings'].get('order')}" + ("" if r["accepted"] else " (refused by accept)")
                          for r in table) or "none fitted"
        raise DataError(f"select_order: no {method} model of the grid (orders {sorted({n for n, _ in pairs})}, horizons "
                        f"{list(dict.fromkeys(h for _, h in pairs))}) is valid for these data"
                        + (f" and accepted by {getattr(accept, '__name__', 'accept')}" if accept is not None else "")
                        + f": {tried}; widen the grid (more orders)")
    return best, table
