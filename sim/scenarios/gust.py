"""``gust``: a discrete 1-cosine wind gust with a null attitude set-point (reference 000, "simulation results
(load disturbance)": process disturbance, typical wind gust, angular set-point null, no measurement noise).

The gust is wind on the twin (fuselage drag, rotor H-force and flapping), not an injected moment. A headwind
gust pitches the vehicle nose up; the metrics score the peak drift and the recovery.

Options
-------
``amplitude_mps`` : float   peak gust speed (default 5.0)
``t_start_s`` : float       gust start (default 2.0)
``gust_s`` : float          gust length (default 1.0)
``from_deg`` : float        direction it comes from, deg clockwise from north (default 0: headwind)
``mean_wind_mps`` : float   steady wind under the gust (default 0)
"""

from __future__ import annotations

from rotorlab.sim.disturbances.cosine_gust import CosineGust
from rotorlab.sim.disturbances.mean_wind import MeanWind
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "gust"
DESCRIPTION = "1-cosine wind gust, null set-point"
SCENES = ("pitch-rig", "roll-rig", "free-flight")
DURATION_S = 8.0
DEFAULTS = {"amplitude_mps": 5.0, "t_start_s": 2.0, "gust_s": 1.0, "from_deg": 0.0, "mean_wind_mps": 0.0}


def options(ctx: Context) -> dict:
    return merged_options(ctx, DEFAULTS)


def setup(ctx: Context) -> Setup:
    o = options(ctx)
    # on the roll rig a gust from the side (from the east, 90 deg) is the one that rolls the vehicle
    from_deg = 90.0 if ctx.scene == "roll-rig" and "from_deg" not in ctx.options else o["from_deg"]
    dist = [CosineGust(o["t_start_s"], o["gust_s"], o["amplitude_mps"], from_deg)]
    if o["mean_wind_mps"]:
        dist.append(MeanWind(o["mean_wind_mps"], from_deg))
    mode = "position" if ctx.scene == "free-flight" else "cascade"
    return Setup(mode=mode, disturbances=dist, sensor_noise=False,
                 notes={"t_gust_s": o["t_start_s"], "gust_s": o["gust_s"], "from_deg": from_deg})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    lim = setup.u_limit_pct or ctx.vehicle.command_limit_pct
    t_gust = setup.notes["t_gust_s"]
    out = {}
    for axis, (angle, _, cmd) in _metrics.AXIS_CHANNELS.items():
        if _metrics.moved(log, angle, 0.05):
            out[axis] = {"disturbance": _metrics.disturbance(log, angle, t_gust),
                         "control": _metrics.control(log, cmd, lim, t_gust)}
    return _metrics.clean(out)
