"""``rope-pull``: the published A2-MINI/B test-bed load-disturbance test (reference 000): a rope at the tip of the
front arm pulled by hand to about 20 deg of pitch, held a couple of seconds, suddenly released; null angular
set-point, command saturation +-40 % (the vehicle's limit), rate set-point saturation +-150 deg/s.

Options
-------
``pull_deg`` : float   imposed pitch, deg (default -20: the rope pulls the front arm down)
``t_pull_s`` : float   start of the pull (default 1.0)
``ramp_s`` : float     duration of the pull (default 0.8)
``hold_s`` : float     hold before the release (default 2.0)
``length_m`` : float   rope length (default 1.0)
"""

from __future__ import annotations

from rotorlab.sim.disturbances.rope_pull import RopePull
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "rope-pull"
DESCRIPTION = "rope at the front-arm tip pulled to ~20 deg, held, released (A2-MINI/B test-bed test)"
SCENES = ("pitch-rig",)
DURATION_S = 8.0
DEFAULTS = {"pull_deg": -20.0, "t_pull_s": 1.0, "ramp_s": 0.8, "hold_s": 2.0, "length_m": 1.0}


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    rope = RopePull(o["pull_deg"], o["t_pull_s"], o["ramp_s"], o["hold_s"], o["length_m"])
    # the published saturations (+-40 %, +-150 deg/s) are the A2-MINI/B's [commands]
    return Setup(mode="cascade", disturbances=[rope],
                 notes={"t_pull_s": rope.t_pull_s, "t_hold_s": rope.t_pull_s + rope.ramp_s,
                        "t_release_s": rope.t_release_s, "pull_deg": rope.pull_deg})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    n = setup.notes
    lim = setup.limits(ctx.vehicle).limit_pct
    hold = _metrics.window(log, n["t_hold_s"], n["t_release_s"])
    after = _metrics.disturbance(log, "theta", n["t_release_s"], band=0.5)
    rel = _metrics.window(log, n["t_release_s"])
    th_after = log["theta"][rel]
    return _metrics.clean({
        "held_angle_deg": float(log["theta"][hold].mean()) if hold.any() else None,
        "peak_tension_N": float(log["rope_tension"].max()) if log.n else None,
        "hold_tension_N": float(log["rope_tension"][hold].mean()) if hold.any() else None,
        "release": after,
        # the published comparison: overshoot past the null set-point after the release (deg, opposite sign)
        "release_overshoot_deg": float(max(0.0, -th_after.min() if n["pull_deg"] > 0 else th_after.max()))
        if th_after.size else None,
        "control": _metrics.control(log, "u_lon", lim),
        "control_after_release": _metrics.control(log, "u_lon", lim, n["t_release_s"]),
    })
