"""ARX by linear least squares: ``A(q) y = B(q) u(k - delay) + e``.

Written here because python-control and scipy fit no ARX. It is biased on closed-loop data where the noise
returns to the input, and by coloured noise in general (the equation error is not white); it is the quick
baseline real-log figures are quoted with, and a candidate for a closed loop seen from its set-point.
"""

from __future__ import annotations

import control as ct
import numpy as np

from rotorlab.errors import DataError

from .model import IdentifiedModel

__all__ = ["arx"]


def arx(u, y, na: int, nb: int, *, dt: float, delay: int = 0) -> IdentifiedModel:
    """ARX(``na``, ``nb``) of ``u -> y`` sampled at ``dt`` (s), as a discrete state-space IdentifiedModel.

    ``B`` starts at lag 0 (``delay = 0``: a direct term, what a closed loop sampled slower than it runs shows),
    ``delay`` (samples) shifts it.

    Raises
    ------
    DataError
        Fewer than ``4 (na + nb)`` equations.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(500)
    >>> y = np.zeros(500)
    >>> for k in range(1, 500):
    ...     y[k] = 0.9 * y[k - 1] + 0.5 * u[k - 1]
    >>> m = arx(u, y, 1, 1, dt=0.01, delay=1)
    >>> float(np.round(m.sys.A[0, 0], 6))
    0.9
    """
    u, y = np.asarray(u, float).ravel(), np.asarray(y, float).ravel()
    n0 = max(na, nb - 1 + delay)
    N = len(y)
    if N - n0 < 4 * (na + nb):
        raise DataError(f"ARX({na},{nb}) needs at least {n0 + 4 * (na + nb)} samples; got {N}")
    cols = [-y[n0 - i:N - i] for i in range(1, na + 1)] + [u[n0 - delay - j:N - delay - j] for j in range(nb)]
    theta = np.linalg.lstsq(np.column_stack(cols), y[n0:], rcond=None)[0]
    a = np.r_[1.0, theta[:na]]
    b = np.r_[theta[na:], np.zeros(max(0, na + 1 - nb))]
    sys = ct.ss(ct.tf(b[:max(na + 1, nb)], np.r_[a, np.zeros(max(0, nb - na - 1))], dt))
    return IdentifiedModel(sys=sys, delay=delay, method="arx", settings={"na": na, "nb": nb})
