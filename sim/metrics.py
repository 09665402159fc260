"""Time-domain performance metrics of logged responses: set-point steps, disturbance recovery, control effort.

Pure numpy/scipy on sampled arrays; crossing times are linearly interpolated between samples so the results do
not jump by a sample period. Every function returns a plain dict whose keys carry the unit.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from rotorlab.errors import DataError


def _arrays(t, y, name="y"):
    t = np.asarray(t, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if t.size != y.size or t.size < 3:
        raise DataError(f"t and {name} must be 1-D of the same length >= 3; got {t.size} and {y.size} samples")
    if np.any(np.diff(t) <= 0):
        raise DataError("t must be strictly increasing")
    if not np.all(np.isfinite(y)):
        raise DataError(f"{name} holds non-finite samples (first at index {int(np.argmin(np.isfinite(y)))})")
    return t, y


def _first_crossing(t, s, level):
    """First time the sequence ``s`` reaches ``level`` from below (linear interpolation), nan if never."""
    idx = np.nonzero(s >= level)[0]
    if idx.size == 0:
        return np.nan
    k = idx[0]
    if k == 0:
        return t[0]
    return t[k - 1] + (level - s[k - 1]) / (s[k] - s[k - 1]) * (t[k] - t[k - 1])


def _last_exit(t, dev, band):
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
    t, y = _arrays(t, y)
    step = float(y_ref_final) - float(y0)
    if step == 0:
        raise DataError("step_metrics needs y_ref_final != y0 (a step of zero size has no rise time)")
    m = t >= t_step
    t, y = t[m], y[m]
    s = (y - y0) / step  # normalised: 0 -> 1 whatever the step's sign
    t10, t90 = _first_crossing(t, s, 0.1), _first_crossing(t, s, 0.9)
    k_pk = int(np.argmax(s))
    n_tail = max(1, int(round(tail_frac * y.size)))
    return {
        "rise_time_s": float(t90 - t10),
        "settling_time_s": float(_last_exit(t, np.abs(s - 1.0), settle_band) - t_step),
        "overshoot_pct": float(max(0.0, s[k_pk] - 1.0) * 100.0),
        "peak": float(y[k_pk]),
        "peak_time_s": float(t[k_pk] - t_step),
        "steady_state_error": float(y_ref_final - np.mean(y[-n_tail:])),
    }


def disturbance_metrics(t, y, t_dist: float, ref: float = 0.0, band: float | None = None,
                        band_frac: float = 0.05) -> dict:
    """Rejection of a disturbance that hits at ``t_dist`` while ``y`` should stay at ``ref``.

    Returns
    -------
    dict
        ``peak_deviation`` (signed, largest ``|y - ref|`` after ``t_dist``), ``peak_time_s`` (from
        ``t_dist``), ``recovery_time_s`` (from ``t_dist`` until ``|y - ref|`` stays within the band; nan if it
        never does), ``band`` (absolute; default ``band_frac`` of ``|peak_deviation|``), ``iae`` (integral of
        ``|y - ref|`` after ``t_dist``, trapezoidal).
    """
    t, y = _arrays(t, y)
    m = t >= t_dist
    if np.count_nonzero(m) < 2:
        raise DataError(f"no samples after t_dist = {t_dist} s (record ends at {t[-1]} s)")
    t, dev = t[m], y[m] - ref
    k = int(np.argmax(np.abs(dev)))
    peak = float(dev[k])
    band = abs(peak) * band_frac if band is None else float(band)
    absdev = np.abs(dev)
    return {
        "peak_deviation": peak,
        "peak_time_s": float(t[k] - t_dist),
        "recovery_time_s": float(_last_exit(t, absdev, band) - t_dist),
        "band": band,
        "iae": float(np.trapezoid(absdev, t)),
    }


def control_metrics(t, u, u_limit: float, hf_cut_hz: float, nperseg: int | None = None) -> dict:
    """Control-effort metrics of a command ``u`` with symmetric saturation ``+-u_limit``.

    Returns
    -------
    dict
        ``rms``, ``peak`` (max ``|u|``), ``time_saturated_s`` and ``time_saturated_pct`` (samples with
        ``|u| >= u_limit``, each counting one sample period), ``hf_power`` (power of ``u`` above ``hf_cut_hz``,
        from the Welch PSD, in ``u``'s unit squared), ``hf_fraction`` (of the total fluctuation power), and
        ``hf_cut_hz`` itself so the number is never quoted without its frequency.
    """
    t, u = _arrays(t, u, "u")
    dt = float(np.median(np.diff(t)))
    if not 0 < hf_cut_hz < 0.5 / dt:
        raise DataError(f"hf_cut_hz must lie between 0 and the Nyquist frequency {0.5 / dt} Hz; got {hf_cut_hz}")
    sat = np.abs(u) >= u_limit * (1.0 - 1e-12)
    nseg = min(u.size, 256 if nperseg is None else int(nperseg))
    f, pxx = signal.welch(u, fs=1.0 / dt, nperseg=nseg, detrend="constant")
    df = f[1] - f[0]
    hf = float(np.sum(pxx[f >= hf_cut_hz]) * df)
    total = float(np.sum(pxx) * df)
    return {
        "rms": float(np.sqrt(np.mean(u * u))),
        "peak": float(np.max(np.abs(u))),
        "time_saturated_s": float(np.count_nonzero(sat) * dt),
        "time_saturated_pct": float(100.0 * np.count_nonzero(sat) / u.size),
        "hf_power": hf,
        "hf_fraction": hf / total if total > 0 else 0.0,
        "hf_cut_hz": float(hf_cut_hz),
    }
