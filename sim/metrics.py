"""Time-domain performance metrics of logged responses: set-point steps (:func:`rotorlab.stepresponse.step_metrics`),
disturbance recovery, control effort.

Pure numpy/scipy on sampled arrays; crossing times are linearly interpolated between samples so the results do
not jump by a sample period. Every function returns a plain dict whose keys carry the unit.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from rotorlab.errors import DataError
from rotorlab.stepresponse import as_series, last_exit, step_metrics

__all__ = ["step_metrics", "disturbance_metrics", "control_metrics"]


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
    t, y = as_series(t, y)
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
        "recovery_time_s": float(last_exit(t, absdev, band) - t_dist),
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
    t, u = as_series(t, u, "u")
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
