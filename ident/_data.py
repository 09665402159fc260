"""Input checks and data shaping shared by the identification routines (private)."""

from __future__ import annotations

import numpy as np

from rotorlab.errors import DataError


def as_columns(x, name: str) -> np.ndarray:
    """``x`` as a float (N, channels) array; 1-D becomes one column. Rejects NaN/inf with their position."""
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise DataError(f"{name}: expected a 1-D array (N,) or a 2-D array (N, channels); got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        k, c = np.argwhere(bad)[0]
        raise DataError(
            f"{name}: {int(bad.sum())} non-finite value(s) (NaN/inf), first at sample {k}, channel {c}; "
            "cut the record around the gap or interpolate it before identification"
        )
    return a


def check_io(u, y, *, min_samples: int, what: str, sized_by: str = "order/horizon") -> tuple[np.ndarray, np.ndarray]:
    """Validate an input/output record and return both as (N, m) / (N, p) arrays; ``sized_by`` names the setting
    that sets ``min_samples`` in the message of a record too short."""
    u2 = as_columns(u, "u")
    y2 = as_columns(y, "y")
    if len(u2) != len(y2):
        raise DataError(f"u has {len(u2)} samples but y has {len(y2)}; pass records of the same length")
    if len(u2) < min_samples:
        raise DataError(
            f"{what} needs at least {min_samples} samples for the requested {sized_by}; got {len(u2)} "
            f"(use a longer record or lower the {sized_by})"
        )
    const = np.ptp(u2, axis=0) == 0
    if const.any():
        raise DataError(
            f"u channel(s) {np.flatnonzero(const).tolist()} are constant: the data carry no information on "
            "the input-output dynamics (excite the input, e.g. with rotorlab.excitation.prbs)"
        )
    return u2, y2


def check_int(value, name: str, lo: int) -> int:
    if int(value) != value or value < lo:
        raise DataError(f"{name} must be a whole number >= {lo}; got {value!r}")
    return int(value)


def shift_delay(u: np.ndarray, y: np.ndarray, delay: int) -> tuple[np.ndarray, np.ndarray]:
    """Align ``u[k - delay]`` with ``y[k]`` (drops the first ``delay`` outputs and last ``delay`` inputs)."""
    if delay == 0:
        return u, y
    return u[: len(u) - delay], y[delay:]


def block_hankel(x: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    """Block-Hankel matrix with ``rows`` block rows of ``x[start + i + j]`` (channels stacked), ``cols`` columns."""
    N, c = x.shape
    # sliding_window_view gives the Hankel structure as a view; one copy makes it contiguous for LAPACK.
    win = np.lib.stride_tricks.sliding_window_view(x[start: start + rows + cols - 1], rows, axis=0)
    # win: (cols, c, rows) -> (rows, c, cols) -> (rows*c, cols)
    return np.ascontiguousarray(win.transpose(2, 1, 0).reshape(rows * c, cols))


def hankel_gram(x: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Gram matrix ``H H^T`` of ``H = block_hankel(x, 0, rows, cols)`` without forming ``H``.

    Block ``(i, j)`` is ``sum_{k < cols} x[i+k] x[j+k]^T``; along each diagonal it obeys
    ``G[i+1, j+1] = G[i, j] - x[i] x[j]^T + x[i+cols] x[j+cols]^T``, so after the first block row the rest
    costs O(rows^2 c^2) instead of the O(N rows^2 c^2) of the dense product (the displacement structure
    SLICOT's fast IB01AD variant exploits too).
    """
    N, c = x.shape
    G = np.empty((rows, rows, c, c))
    x0 = x[:cols]
    for j in range(rows):
        G[0, j] = x0.T @ x[j: j + cols]
    for i in range(1, rows):
        a, b = x[i - 1], x[i - 1 + cols]
        G[i, i:] = (G[i - 1, i - 1: rows - 1] - a[None, :, None] * x[i - 1: rows - 1, None, :]
                    + b[None, :, None] * x[i - 1 + cols: rows - 1 + cols, None, :])
    iu = np.triu_indices(rows, 1)
    G[iu[1], iu[0]] = G[iu].transpose(0, 2, 1)
    return G.transpose(0, 2, 1, 3).reshape(rows * c, rows * c)
