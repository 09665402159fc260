"""The metrics a control engineer reads first, per scenario, with labels and units.

Scenario metrics (``run.json`` -> ``metrics``) are nested dicts whose keys carry units only sometimes
(``rise_time_s`` but ``control.rms``); :func:`key_rows` turns the flattened form
(:func:`rotorlab.keymetrics.flatten_metrics`) into ``(key, label, unit, value)`` rows that lead with the
scenario's key metrics (set-point: rise, overshoot, settling, steady-state error; disturbances: peak,
IAE, recovery; hover: RMS errors) and then the rest, settings left out. ``rotorlab run``, ``rotorlab
montecarlo`` and the pipeline report all read them from here, so the same metric has the same name and
unit everywhere.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["KEY_METRICS", "flatten_metrics", "key_rows", "unit_of", "lookup", "fmt"]

#: scenario -> [(flat key, label, unit)]; ``{axis}`` expands to pitch and roll, a hover key is looked up in the
#: phase after the in-flight gain switch, else over the whole run (see :func:`lookup`)
KEY_METRICS = {
    "setpoint": [
        ("steps.mean.rise_time_s", "rise time 10-90 %, mean over steps", "s"),
        ("steps.mean.overshoot_pct", "overshoot, mean over steps", "%"),
        ("steps.mean.settling_time_s", "settling time 2 %, mean over steps", "s"),
        ("steady_state_error_max_abs_deg", "steady-state error, largest over steps", "deg"),
        ("control.rms", "command RMS", "%"),
        ("control.time_saturated_pct", "time in saturation", "%"),
        ("control.hf_power", "command power above 5 Hz", "%^2"),
    ],
    "gust": [
        ("{axis}.disturbance.peak_deviation", "{axis} peak deviation", "deg"),
        ("{axis}.disturbance.iae", "{axis} IAE", "deg s"),
        ("{axis}.disturbance.recovery_time_s", "{axis} recovery time (5 % band)", "s"),
        ("{axis}.control.rms", "{axis} command RMS", "%"),
        ("{axis}.control.peak", "{axis} command peak", "%"),
    ],
    "rope-pull": [
        ("release_overshoot_deg", "overshoot after release", "deg"),
        ("release.peak_deviation", "peak deviation after release", "deg"),
        ("release.iae", "IAE after release", "deg s"),
        ("release.recovery_time_s", "recovery time after release (0.5 deg band)", "s"),
        ("held_angle_deg", "angle held by the rope", "deg"),
        ("control_after_release.rms", "command RMS after release", "%"),
    ],
    "hover": [
        ("pitch.rms_error_deg", "pitch RMS error", "deg"),
        ("roll.rms_error_deg", "roll RMS error", "deg"),
        ("position_error_rms_m", "horizontal position RMS error", "m"),
        ("altitude_error_rms_m", "altitude RMS error", "m"),
        ("pitch.control.rms", "pitch command RMS", "%"),
        ("roll.control.rms", "roll command RMS", "%"),
    ],
    "prbs": [
        ("max_abs_angle_deg", "largest attitude excursion", "deg"),
        ("supervisor_active_pct", "time the supervisor acted", "%"),
        ("rms_rate_dps", "rate RMS", "deg/s"),
        ("control.rms", "command RMS", "%"),
    ],
    "prbs-closed": [
        ("rms_tracking_error_deg", "tracking RMS error", "deg"),
        ("control.rms", "command RMS", "%"),
    ],
    "prbs-flight": [
        ("max_abs_pitch_deg", "largest pitch excursion", "deg"),
        ("position_error_max_m", "largest position error", "m"),
        ("control.rms", "command RMS", "%"),
    ],
    "thrust-sweep": [
        ("thrust_slope_N_per_rad", "thrust slope dT/d(blade pitch)", "N/rad"),
        ("k_thrust_N_per_rad2_s2", "thrust coefficient K_T (T = K_T Omega^2)", "N/(rad/s)^2"),
    ],
    "thrust-steps": [
        ("time_constant_s", "first-order time constant, median", "s"),
        ("delay_s", "delay, median", "s"),
    ],
}

#: hover phases in the order a key is looked for: after the in-flight switch, else the whole run
HOVER_PHASES = ("after_switch", "all", "before_switch")

#: settings and bookkeeping that are not results (left out of every table)
_NOT_RESULTS = ("hf_cut_hz", ".band", "from_deg", "to_deg", ".t_s", "mean_ref_deg", "supervisor_limit_deg",
                "hf_fraction", "time_saturated_s", "peak_time_s", "steps.mean.peak", "steady_state_error")

# unit from the name's suffix (the project's convention: names carry units)
# (tried longest first, so "_rad_s" is rad/s and not s)
_SUFFIX_UNITS = sorted({"_N_per_rad": "N/rad", "_N_per_rad2_s2": "N/(rad/s)^2", "_pct": "%", "_deg": "deg",
                        "_dps": "deg/s", "_mps": "m/s", "_s": "s", "_m": "m", "_Nm": "N m", "_N": "N", "_hz": "Hz",
                        "_rad_s": "rad/s"}.items(), key=lambda kv: -len(kv[0]))
# unit of a command metric (commands are in %) and of the angle metrics without a suffix
_LEAF_UNITS = {"rms": "%", "peak": "%", "hf_power": "%^2", "peak_deviation": "deg", "iae": "deg s"}


def flatten_metrics(m, prefix: str = "") -> dict:
    """Scenario metrics as one flat ``{"a.b": number}`` dict; a list of dicts (e.g. one per step) becomes the
    mean of each numeric key under ``"<key>.mean.<name>"``."""
    out = {}
    if isinstance(m, dict):
        for k, v in m.items():
            out.update(flatten_metrics(v, f"{prefix}{k}."))
    elif isinstance(m, (list, tuple)) and m and all(isinstance(x, dict) for x in m):
        rows = [flatten_metrics(x) for x in m]
        for k in sorted(set().union(*rows)):
            vals = [r[k] for r in rows if k in r and r[k] is not None]
            if vals:
                out[f"{prefix}mean.{k}"] = float(np.mean(vals))
    elif isinstance(m, bool) or m is None:
        pass
    elif isinstance(m, (int, float)) and math.isfinite(m):
        out[prefix[:-1]] = float(m)
    return out


def unit_of(key: str) -> str:
    """Unit of a flat metric key from its name (``""`` when it names none)."""
    leaf = key.rsplit(".", 1)[-1]
    if leaf in _LEAF_UNITS:
        return _LEAF_UNITS[leaf]
    for suffix, unit in _SUFFIX_UNITS:
        if leaf.endswith(suffix):
            return unit
    return ""


def lookup(flat: dict, key: str):
    """``flat[key]``, looking a hover key up in the phase after the switch, else over the whole run."""
    if key in flat:
        return flat[key]
    for phase in HOVER_PHASES:
        if f"{phase}.{key}" in flat:
            return flat[f"{phase}.{key}"]
    return None


def _expand(scenario: str, flat: dict) -> list[tuple[str, str, str]]:
    rows = []
    for key, label, unit in KEY_METRICS.get(scenario, []):
        if "{axis}" in key:
            rows += [(key.format(axis=a), label.format(axis=a), unit) for a in ("pitch", "roll")]
        else:
            rows.append((key, label, unit))
    return rows


def key_rows(scenario: str, flats: dict | list, rest: bool = True) -> list[tuple[str, str, str, list]]:
    """Table rows ``(key, label, unit, values)`` of one or several runs of ``scenario``.

    Parameters
    ----------
    scenario : str
        Scenario name (selects its key metrics).
    flats : dict or list of dict
        Flattened metrics of one run, or of several runs (one column each).
    rest : bool
        Append the other result metrics (labelled by their key) after the key ones.

    Returns
    -------
    list of (key, label, unit, values)
        ``values`` holds one number (or None) per run; rows where every run lacks the metric are dropped.
    """
    runs = [flats] if isinstance(flats, dict) else list(flats)
    rows, used = [], set()
    for key, label, unit in _expand(scenario, runs[0] if runs else {}):
        vals = [lookup(f, key) for f in runs]
        if any(v is not None for v in vals):
            rows.append((key, label, unit, vals))
        used |= {key} | {f"{p}.{key}" for p in HOVER_PHASES}
    if rest:
        keys = sorted(set().union(*runs)) if runs else []
        for k in keys:
            if k in used or any(s in k for s in _NOT_RESULTS):
                continue
            rows.append((k, k, unit_of(k), [f.get(k) for f in runs]))
    return rows


def fmt(x, digits: int = 4) -> str:
    """A number for people: ``digits`` significant digits, ``-`` for missing or non-finite (never a numpy repr)."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"
