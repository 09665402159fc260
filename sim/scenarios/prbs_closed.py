"""``prbs-closed``: PRBS with the nominal attitude controller closed (reference 000: the validation data were
taken in closed loop). The PRBS is added to the angle set-point (default) or to the axis command inside the
inner PID (``target = 'command'``).

Options
-------
``target`` : str          ``setpoint`` (default) or ``command``
``amplitude`` : float     PRBS level, deg for the set-point (default 3) or % for the command (default 7)
``hold_range_s`` : list   level-hold range, s (default [0.2, 0.4])
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.excitation import prbs
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "prbs-closed"
DESCRIPTION = "PRBS on the set-point or the command with the nominal cascade closed"
SCENES = ("pitch-rig", "roll-rig")
DURATION_S = 60.0
DEFAULTS = {"target": "setpoint", "amplitude": None, "hold_range_s": [0.2, 0.4]}
SEED_TAG = 0x70726263


def signal(ctx: Context, defaults: dict, target_names: dict, default_amp: dict):
    """Validate the options against ``defaults`` and draw the PRBS: ``(target, amplitude, samples)``."""
    o = merged_options(ctx, defaults)
    if o["target"] not in target_names:
        raise ConfigError(field="options.target", expected=f"one of {sorted(target_names)}", got=o["target"])
    amp = float(o["amplitude"] if o["amplitude"] is not None else default_amp[o["target"]])
    u = prbs(duration_s=ctx.duration_s, dt=ctx.dt_s, hold_range_s=tuple(o["hold_range_s"]), amplitude=amp,
             rng=np.random.default_rng([ctx.seed, SEED_TAG]))
    return o["target"], amp, u


def setup(ctx: Context) -> Setup:
    axis, angle, _, cmd = _metrics.channels(ctx.scene)
    target, amp, u = signal(ctx, DEFAULTS, {"setpoint": f"{angle}_ref", "command": cmd},
                            {"setpoint": 3.0, "command": 7.0})
    name = f"{angle}_ref" if target == "setpoint" else cmd
    return Setup(mode="cascade", excitation={name: u}, notes={"target": name, "amplitude": amp, "axis": axis})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    axis, angle, _, cmd = _metrics.channels(ctx.scene)
    err = log[angle] - log[f"{angle}_ref"]
    return _metrics.clean({"axis": axis, "rms_tracking_error_deg": float((err ** 2).mean() ** 0.5) if err.size else None,
                           "control": _metrics.control(log, cmd, setup.u_limit_pct or ctx.vehicle.command_limit_pct)})
