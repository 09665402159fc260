"""Shared scoring of scenario logs with :mod:`rotorlab.sim.metrics`: JSON-safe dicts, per-axis channel names."""

from __future__ import annotations

import math

import numpy as np

from rotorlab.sim.metrics import control_metrics, disturbance_metrics, step_metrics

#: high-frequency control activity is the power of the command above this frequency (Hz): above every loop's
#: crossover (at most 14 rad/s = 2.2 Hz in the published requirements) and below the 25 Hz Nyquist frequency
HF_CUT_HZ = 5.0

#: rig scene -> (axis, angle column, rate column, command column)
AXIS_CHANNELS = {"pitch": ("theta", "q", "u_lon"), "roll": ("phi", "p", "u_lat")}


def channels(scene: str) -> tuple[str, str, str, str]:
    """(axis, angle, rate, command) log columns of the axis a rig scene moves (pitch for free flight)."""
    axis = "roll" if scene == "roll-rig" else "pitch"
    return (axis, *AXIS_CHANNELS[axis])


def clean(obj):
    """Floats that JSON can hold: NaN/inf become None, numpy scalars plain floats (recursively)."""
    if isinstance(obj, dict):
        return {k: clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def window(log, t0: float, t1: float = math.inf):
    """Boolean mask of the log rows with ``t0 <= t < t1``."""
    t = log["t"]
    return (t >= t0 - 1e-9) & (t < t1 - 1e-9)


def control(log, column: str, u_limit: float, t0: float = 0.0, t1: float = math.inf) -> dict:
    """Control metrics of a command column over ``[t0, t1)`` (s); empty when fewer than 3 samples."""
    m = window(log, t0, t1)
    if np.count_nonzero(m) < 8:
        return {}
    return control_metrics(log["t"][m], log[column][m], u_limit, HF_CUT_HZ, nperseg=min(256, int(np.count_nonzero(m))))


def step(log, column: str, t_step: float, t_end: float, y0: float, y_final: float) -> dict:
    """Step metrics of ``column`` for a set-point step from ``y0`` to ``y_final`` at ``t_step`` (s), scored up to
    ``t_end``; ``{}`` when the run stopped before the step had 3 samples."""
    m = window(log, t_step, t_end)
    if np.count_nonzero(m) < 3:
        return {}
    return step_metrics(log["t"][m], log[column][m], y_final, y0=y0, t_step=t_step)


def disturbance(log, column: str, t_dist: float, ref: float = 0.0, t_end: float = math.inf, band=None) -> dict:
    """Disturbance metrics of ``column`` after ``t_dist`` (s) up to ``t_end``."""
    m = window(log, 0.0, t_end)
    if np.count_nonzero(m & (log["t"] >= t_dist)) < 3:
        return {}
    return disturbance_metrics(log["t"][m], log[column][m], t_dist, ref=ref, band=band)


def moved(log, column: str, threshold: float) -> bool:
    """Whether a column's peak-to-peak exceeds ``threshold`` (so its axis is scored)."""
    y = log[column]
    y = y[np.isfinite(y)]
    return y.size > 0 and float(np.ptp(y)) > threshold
