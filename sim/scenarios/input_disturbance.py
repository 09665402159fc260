"""``input-disturbance``: a step input disturbance on the rig with a null set-point (ref. 002 figs. 6 and 8).

``fraction`` of the full differential command is added at the plant input (the rotor commands, upstream of the
motors' delay and lag) from ``t0_s`` on
(:class:`~rotorlab.sim.disturbances.input_disturbance_step.InputDisturbanceStep`). 10 % is the paper's linear test
(H-inf about 4 deg against 15 deg for the modified PID); 30 % saturates the TUHH twin's 40 % command limit (the
anti-windup test: unstable without the compensator, recovered with it).

Options
-------
``fraction`` : float    disturbance, fraction of full command (default 0.1)
``t0_s`` : float        onset, s (default 1.0)
``band_deg`` : float    recovery band around the set-point, deg (default 0.5)
"""

from __future__ import annotations

from rotorlab.errors import ConfigError
from rotorlab.sim.disturbances.input_disturbance_step import InputDisturbanceStep
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "input-disturbance"
DESCRIPTION = "step input disturbance (fraction of full command) on the rig, null set-point"
SCENES = ("pitch-rig", "roll-rig")
DURATION_S = 8.0
DEFAULTS = {"fraction": 0.1, "t0_s": 1.0, "band_deg": 0.5}


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    if not o["band_deg"] > 0:
        raise ConfigError(field="options.band_deg", expected="a band > 0 deg", got=o["band_deg"])
    axis = _metrics.channels(ctx.scene)[0]
    return Setup(mode="cascade", disturbances=[InputDisturbanceStep(float(o["fraction"]), float(o["t0_s"]))],
                 notes={"axis": axis, "fraction": float(o["fraction"]), "t_dist_s": float(o["t0_s"]),
                        "band_deg": float(o["band_deg"])})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    axis, angle, _, cmd = _metrics.channels(ctx.scene)
    n = setup.notes
    lim = setup.u_limit_pct or ctx.vehicle.command_limit_pct
    return _metrics.clean({axis: {"disturbance": _metrics.disturbance(log, angle, n["t_dist_s"], band=n["band_deg"]),
                                  "control": _metrics.control(log, cmd, lim, n["t_dist_s"])}})
