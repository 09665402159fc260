"""``prbs-flight``: in-flight identification data: hover at 5 m with mean wind and turbulence, position hold
active, PRBS on the pitch command (reference 000, in-flight PRBS experiments; the attitude loop stays closed so
the flight is safe, the PRBS enters inside the inner PID before its saturation).

Options
-------
``target`` : str          ``command`` (default, PRBS on u_lon in %) or ``setpoint`` (on theta_ref in deg)
``amplitude`` : float     default 7 % (command) or 3 deg (set-point)
``hold_range_s`` : list   level-hold range, s (default [0.1, 0.2])
``wind_mps`` : float      mean wind, headwind (default 2.5)
``turbulence`` : bool     Dryden turbulence on (default True)
"""

from __future__ import annotations

from rotorlab.scenes import HOVER_HEIGHT_M
from rotorlab.sim.disturbances.mean_wind import MeanWind
from rotorlab.sim.disturbances.dryden_wind import DrydenWind
from rotorlab.sim.scenarios import Context, Setup, _metrics
from rotorlab.sim.scenarios.prbs_closed import signal

NAME = "prbs-flight"
DESCRIPTION = "PRBS on the pitch command in hover with wind and position hold"
SCENES = ("free-flight",)
DURATION_S = 60.0
DEFAULTS = {"target": "command", "amplitude": None, "hold_range_s": [0.1, 0.2], "wind_mps": 2.5, "turbulence": True}


def setup(ctx: Context) -> Setup:
    o = {**DEFAULTS, **ctx.options}
    target, amp, u = signal(ctx, DEFAULTS, {"setpoint": "theta_ref", "command": "u_lon"},
                            {"setpoint": 3.0, "command": 7.0})
    name = "theta_ref" if target == "setpoint" else "u_lon"
    dist = []
    if o["wind_mps"]:
        dist.append(MeanWind(o["wind_mps"]))
        if o["turbulence"]:
            dist.append(DrydenWind(o["wind_mps"], HOVER_HEIGHT_M, ctx.duration_s))
    return Setup(mode="position", excitation={name: u}, disturbances=dist, notes={"target": name, "amplitude": amp})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    m = _metrics.window(log, 0.0)
    pos = ((log["x"] - log["x_ref"]) ** 2 + (log["y"] - log["y_ref"]) ** 2) ** 0.5
    return _metrics.clean({
        "max_abs_pitch_deg": float(abs(log["theta"]).max()) if m.any() else None,
        "position_error_max_m": float(pos.max()) if m.any() else None,
        "control": _metrics.control(log, "u_lon", setup.u_limit_pct or ctx.vehicle.command_limit_pct),
    })
