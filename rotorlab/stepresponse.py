"""Step-response metrics of a sampled response: the one definition shared by the scenario metrics
(:mod:`rotorlab.sim.metrics`) and the model analysis (:mod:`rotorlab.tune.montecarlo`, the pipeline's linear
steps), so a rise time means the same wherever it is reported.

Pure numpy; crossing times are linearly interpolated between samples so the results do not jump by a sample
period. Keys carry the unit.
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import DataError

__all__ = ["step_metrics", "as_series", "first_crossing", "last_exit"]


def as_series(t, y, name="y"):
    """``t`` and ``y`` as 1-D float arrays of the same length >= 3, ``t`` strictly increasing, ``y`` finite."""
    t = np.asarray(t, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if t.size != y.size or t.size < 3:
        raise DataError(f"t and {name} must be 1-D of the same length >= 3; got {t.size} and {y.size} samples")
    if np.any(np.diff(t) <= 0):
        raise DataError("t must be strictly increasing")
    if not np.all(np.isfinite(y)):
        raise DataError(f"{name} holds non-finite samples (first at index {int(np.argmin(np.isfinite(y)))})")
    return t, y


def first_crossing(t, s, level):
    """First time the sequence ``s`` reaches ``level`` from below (linear interpolation), nan if never."""
    idx = np.nonzero(s >= level)[0]
    if idx.size == 0:
        return np.nan
    k = idx[0]
    if k == 0:
        return t[0]
    return t[k - 1] + (level - s[k - 1]) / (s[k] - s[k - 1]) * (t[k] - t[k - 1])


def last_exit(t, dev, band):
    """Time after which ``dev`` stays within ``band`` for good: the interpolated crossing back into the band
    after its last violation; ``t[0]`` if never outside, nan if still outside at the end."""
    out = np.nonzero(dev > band)[0]
    if out.size == 0:
        return t[0]
    k = out[-1]
    if k == dev.size - 1:
        return np.nan
    return t[k] + (dev[k] - band) / (dev[k] - dev[k + 1]) * (t[k + 1] - t[k])


def step_metrics(t, y, y_ref_final: float, y0: float = 0.0, t_step: float = 0.0, settle_band: float = 0.02,
                 tail_frac: float = 0.05) -> dict:
    """Step-response metrics of ``y`` for a set-point step from ``y0`` to ``y_ref_final`` at ``t_step``.

    Returns
    -------
    dict
        ``rise_time_s`` (10 % -> 90 % of the step, interpolated), ``settling_time_s`` (from ``t_step`` until
        ``|y - y_ref_final|`` stays within ``settle_band`` (2 %) of the step size), ``overshoot_pct`` (of the
        step size, 0 when none), ``peak`` and ``peak_time_s`` (from ``t_step``), ``steady_state_error``
        (``y_ref_final`` minus the mean of the last ``tail_frac`` of the record). Times are nan when the
        response never gets there.
    """
    t, y = as_series(t, y)
    step = float(y_ref_final) - float(y0)
    if step == 0:
        raise DataError("step_metrics needs y_ref_final != y0 (a step of zero size has no rise time)")
    m = t >= t_step
    t, y = t[m], y[m]
    s = (y - y0) / step  # normalised: 0 -> 1 whatever the step's sign
    t10, t90 = first_crossing(t, s, 0.1), first_crossing(t, s, 0.9)
    k_pk = int(np.argmax(s))
    n_tail = max(1, int(round(tail_frac * y.size)))
    return {
        "rise_time_s": float(t90 - t10),
        "settling_time_s": float(last_exit(t, np.abs(s - 1.0), settle_band) - t_step),
        "overshoot_pct": float(max(0.0, s[k_pk] - 1.0) * 100.0),
        "peak": float(y[k_pk]),
        "peak_time_s": float(t[k_pk] - t_step),
        "steady_state_error": float(y_ref_final - np.mean(y[-n_tail:])),
    }
