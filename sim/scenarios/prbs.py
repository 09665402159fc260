"""``prbs``: the published quasi-open-loop identification experiment on the rig (reference 000): nominal
attitude controllers off, the supervisor keeping the attitude within +-20 deg, PRBS on the axis command.

The input is the published campaign: three PRBS segments concatenated, amplitudes 7, 9 and 11 %, each with its
level-hold range from the published table. By default the ranges are designed for the vehicle's campaign band
(``[campaign] band_rad_s`` in its TOML, ref. 000: 4-8 rad/s for the P2-A2, 3-7 for the A2-MINI/B) with
:func:`rotorlab.excitation.design_campaign`: a hold near T puts the power near pi/T, so the 0.4-0.8 s range
carries about 70 % of its power into those bands where the shorter ranges carry under 5 %.
The log holds, at 50 Hz, the command (``u_lon``/``u_lat``: PRBS plus supervisor), the supervisor's share
(``sup_lon``/``sup_lat``) and the IMU outputs (angle, rate, rate derivative).

Options
-------
``segment_s`` : float     length of each segment (default: a third of the run)
``holds`` : list          hold-range index (0..3 into the published table) of each segment (default: designed)
``amplitudes_pct`` : list amplitudes of the segments (default [7, 9, 11])
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.excitation import ANTEOS_CAMPAIGN, campaign, design_campaign
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "prbs"
DESCRIPTION = "quasi-open-loop PRBS campaign on the rig with the +-20 deg supervisor"
SCENES = ("pitch-rig", "roll-rig")
DURATION_S = 90.0
DEFAULTS = {"segment_s": None, "holds": None, "amplitudes_pct": [7.0, 9.0, 11.0]}
SUPERVISOR_LIMIT_DEG = 20.0


def excitation(ctx: Context, defaults: dict = DEFAULTS) -> tuple[np.ndarray, list]:
    """The concatenated PRBS (%, one sample per tick) and its segment table, seeded by the run seed."""
    o = merged_options(ctx, defaults)
    amps = [float(a) for a in o["amplitudes_pct"]]
    holds = list(o["holds"]) if o["holds"] is not None else list(
        design_campaign(campaign_band(ctx.vehicle), n_segments=len(amps), amplitudes_pct=amps).holds)
    if len(holds) != len(amps) or not holds:
        raise ConfigError(field="options.holds/amplitudes_pct", expected="lists of the same non-zero length",
                          got=(holds, amps))
    table = ANTEOS_CAMPAIGN["hold_ranges_s"]
    for h in holds:
        if not (isinstance(h, int) and 0 <= h < len(table)):
            raise ConfigError(field="options.holds", expected=f"indices 0..{len(table) - 1} into {table}", got=h)
    seg = float(o["segment_s"] or ctx.duration_s / len(holds))
    segments = [(table[h], a, seg) for h, a in zip(holds, amps)]
    u, _ = campaign(segments, dt=ctx.dt_s, seed=np.random.default_rng([ctx.seed, 0x70727273]))
    return u, [[list(s[0]), s[1], s[2]] for s in segments]


def campaign_band(vehicle) -> tuple:
    """The band (rad/s) the vehicle's campaign aims at: its ``[campaign]`` table, else the published P2-A2 one."""
    return tuple(vehicle.campaign_band_rad_s or ANTEOS_CAMPAIGN["band_rad_s"])


def setup(ctx: Context) -> Setup:
    u, segments = excitation(ctx)
    axis, _, _, cmd = _metrics.channels(ctx.scene)
    return Setup(mode="open-loop", excitation={cmd: u}, open_loop_axes=(axis,),
                 extra_columns={"sup_lon": "%", "sup_lat": "%", "u_exc": "%"},
                 on_tick=_exc_logger(u), notes={"segments": segments, "axis": axis})


def _exc_logger(u):
    k = {"i": 0}

    def on_tick(sim, out: dict) -> dict:
        i = k["i"]
        k["i"] = i + 1
        return {"u_exc": float(u[i]) if i < len(u) else 0.0}

    return on_tick


def metrics(log, ctx: Context, setup: Setup) -> dict:
    axis, angle, rate, cmd = _metrics.channels(ctx.scene)
    sup = "sup_lat" if axis == "roll" else "sup_lon"
    ang = log[angle]
    return _metrics.clean({
        "axis": axis,
        "max_abs_angle_deg": float(np.abs(ang).max()) if ang.size else None,
        "supervisor_limit_deg": SUPERVISOR_LIMIT_DEG,
        "supervisor_active_pct": float(100.0 * np.mean(log[sup] != 0.0)) if ang.size else None,
        "rms_rate_dps": float(np.sqrt(np.mean(log[rate] ** 2))) if ang.size else None,
        "control": _metrics.control(log, cmd, setup.u_limit_pct or ctx.vehicle.command_limit_pct),
    })
