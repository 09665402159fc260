"""``prbs-flight``: the published in-flight identification experiment (reference 000, 001): hover at 5 m with
mean wind and turbulence, PRBS on the pitch command.

``protocol = "quasi-open-loop"`` (default) is the paper's: the nominal attitude and position controllers are off
on the excited axis and only the +-20 deg attitude supervisor acts ("more invasive during in-flight
identification ... in presence of wind disturbances"); the input is the same three concatenated PRBS segments
at +-7/9/11 % as the test-bed campaign (:func:`rotorlab.sim.scenarios.prbs.excitation`, holds designed for the
vehicle's band). The paper's vehicle was held in altitude and heading by its pilot: here an altitude hold and the
roll and heading loops stay closed, which leaves the pitch/speed dynamics free, as in the paper.

``protocol = "position-hold"`` is the safer variant: cascade and position hold closed, the same PRBS added to the
pitch command inside the inner PID (closed-loop data: the identified model is biased by the feedback).

The log holds ``u_lon`` (PRBS plus supervisor), the supervisor's share ``sup_lon`` and the PRBS alone ``u_exc``.

Options
-------
``protocol`` : str
    ``quasi-open-loop`` (default) or ``position-hold``.
``segment_s``, ``holds``, ``amplitudes_pct``:
    the campaign, as in ``prbs`` (default [7, 9, 11] %, designed holds).
``wind_mps`` : float
    Mean wind, headwind (default 2.5 m/s: ref. 000 does not give the wind of the P2-A2's in-flight identification;
    this is the mean wind of its A2-MINI/B flight test).
``turbulence`` : bool
    Dryden turbulence on (default True), gust gradients included: ref. 000 puts the wider in-flight uncertainty
    band down to "the presence of wind gust" (less repeatable conditions than the test-bed); the gradients' pitch
    moment on the rotors' damping is the in-band part of it (in hover at 2.5 m/s most of the horizontal gusts'
    power lies below 0.1 rad/s, and the vertical gust reaches the pitch axis only through the collective).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.scenes import HOVER_HEIGHT_M
from rotorlab.sim.disturbances.dryden_wind import DrydenWind
from rotorlab.sim.disturbances.mean_wind import MeanWind
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options
from rotorlab.sim.scenarios.prbs import SUPERVISOR_LIMIT_DEG, _exc_logger, excitation

NAME = "prbs-flight"
DESCRIPTION = "in-flight PRBS campaign in hover with wind: quasi-open-loop with the supervisor (or position hold)"
SCENES = ("free-flight",)
DURATION_S = 90.0
PROTOCOLS = ("quasi-open-loop", "position-hold")
DEFAULTS = {"protocol": "quasi-open-loop", "segment_s": None, "holds": None, "amplitudes_pct": [7.0, 9.0, 11.0],
            "wind_mps": 2.5, "turbulence": True}
CAMPAIGN_KEYS = ("segment_s", "holds", "amplitudes_pct")


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    if o["protocol"] not in PROTOCOLS:
        raise ConfigError(field="options.protocol", expected=f"one of {list(PROTOCOLS)}", got=o["protocol"])
    u, segments = excitation(dataclasses.replace(ctx, options={k: o[k] for k in CAMPAIGN_KEYS}))
    dist = []
    if o["wind_mps"]:
        dist.append(MeanWind(o["wind_mps"]))
        if o["turbulence"]:
            dist.append(DrydenWind(o["wind_mps"], HOVER_HEIGHT_M, ctx.duration_s))
    notes = {"protocol": o["protocol"], "segments": segments, "axis": "pitch"}
    extra = {"sup_lon": "%", "sup_lat": "%", "u_exc": "%"}
    if o["protocol"] == "position-hold":
        return Setup(mode="position", excitation={"u_lon": u}, disturbances=dist, extra_columns={"u_exc": "%"},
                     on_tick=_exc_logger(u), notes=notes)
    # the pilot's altitude hold: the altitude loop holds the height latched at the first tick
    return Setup(mode="open-loop", open_loop_axes=("pitch",), altitude_hold=True,
                 excitation={"u_lon": u}, disturbances=dist, extra_columns=extra, on_tick=_exc_logger(u), notes=notes)


def metrics(log, ctx: Context, setup: Setup) -> dict:
    m = _metrics.window(log, 0.0)
    th = log["theta"]
    pos = ((log["x"] - log["x"][0]) ** 2 + (log["y"] - log["y"][0]) ** 2) ** 0.5 if m.any() else np.zeros(0)
    out = {
        "protocol": setup.notes["protocol"],
        "max_abs_pitch_deg": float(np.abs(th).max()) if m.any() else None,
        "position_drift_max_m": float(pos.max()) if m.any() else None,
        "control": _metrics.control(log, "u_lon", setup.u_limit_pct or ctx.vehicle.command_limit_pct),
    }
    if setup.notes["protocol"] == "quasi-open-loop":
        out["supervisor_limit_deg"] = SUPERVISOR_LIMIT_DEG
        out["supervisor_active_pct"] = float(100.0 * np.mean(log["sup_lon"] != 0.0)) if m.any() else None
    return _metrics.clean(out)
