"""``setpoint``: attitude set-point steps on the rig (reference 000, "simulation results (set-point tracking)").

The sequence starts with a 0.3 deg step with the IMU noise off: the standard gains' derivative kick moves the
command by about 60 % per degree of set-point, so only a small step stays linear and can be compared with a
discrete linear analysis (tests/test_published_loop.py). The noise (if the run has it) then comes on and steps
of both signs and growing size follow, the last large enough to saturate the command.

Options
-------
``steps_deg`` : list of float
    Set-point levels after the small step, each held ``hold_s`` and followed by a return to 0
    (default ``[2, -2, 5, -5, 10, -10]``).
``small_step_deg`` : float
    The first, noise-free step (default 0.3; 0 skips it).
``hold_s`` : float
    Time at each level, s (default 2.5).
``t0_s`` : float
    Time of the first step, s (default 1.0).
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "setpoint"
DESCRIPTION = "set-point steps (0.3 deg noise-free, then both signs, up to saturation)"
SCENES = ("pitch-rig", "roll-rig")
DURATION_S = 31.0
DEFAULTS = {"steps_deg": [2.0, -2.0, 5.0, -5.0, 10.0, -10.0], "small_step_deg": 0.3, "hold_s": 2.5, "t0_s": 1.0}


def schedule(o: dict) -> list[tuple[float, float]]:
    """(time s, level deg) of every set-point change, from the options merged over :data:`DEFAULTS`."""
    hold, t = float(o["hold_s"]), float(o["t0_s"])
    if not hold > 0:
        raise ConfigError(field="options.hold_s", expected="a hold time > 0 s", got=hold)
    levels = ([float(o["small_step_deg"])] if o["small_step_deg"] else []) + [float(s) for s in o["steps_deg"]]
    out = []
    for lvl in levels:
        out += [(t, lvl), (t + hold, 0.0)]
        t += 2 * hold
    return out


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    changes = schedule(o)
    times = np.array([c[0] for c in changes])
    levels = np.array([c[1] for c in changes])
    axis, angle, _, _ = _metrics.channels(ctx.scene)
    ref_name = f"{angle}_ref"
    small = bool(o["small_step_deg"])
    # noise off over the small step and its return, until the next step starts
    quiet_until = float(times[2]) if small and len(times) > 2 else (np.inf if small else 0.0)

    def reference(t: float) -> dict:
        k = np.searchsorted(times, t + 1e-9) - 1
        return {ref_name: float(levels[k]) if k >= 0 else 0.0}

    return Setup(mode="cascade", reference=reference, noise_on=lambda t: t >= quiet_until - 1e-9, sensor_noise=True,
                 notes={"steps": [list(c) for c in changes], "axis": axis, "noise_off_until_s": quiet_until if np.isfinite(quiet_until) else None})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    axis, angle, _, cmd = _metrics.channels(ctx.scene)
    changes = setup.notes["steps"]
    lim = setup.u_limit_pct or ctx.vehicle.command_limit_pct
    steps, prev = [], 0.0
    for i, (t, lvl) in enumerate(changes):
        t_end = changes[i + 1][0] if i + 1 < len(changes) else np.inf
        if lvl != prev:
            m = _metrics.step(log, angle, t, t_end, prev, lvl)
            if m:
                m.update(from_deg=prev, to_deg=lvl, t_s=t,
                         control=_metrics.control(log, cmd, lim, t, min(t_end, t + 2.0)))
                steps.append(m)
        prev = lvl
    # the signed errors of steps of both signs cancel in a mean: the summary is the largest magnitude
    sse = [abs(m["steady_state_error"]) for m in steps if np.isfinite(m["steady_state_error"])]
    out = {"axis": axis, "steps": steps, "steady_state_error_max_abs_deg": max(sse) if sse else None,
           "control": _metrics.control(log, cmd, lim)}
    # the noise-free small step is the linear one (comparable with a linear analysis); the others saturate
    # the command and are scored apart, so a mean never mixes the two regimes
    small = float({**DEFAULTS, **ctx.options}["small_step_deg"] or 0.0)
    linear = [m for m in steps if small and abs(m["to_deg"] - m["from_deg"]) <= small + 1e-9][:1]
    if linear:
        out["linear_step"] = linear[0]
    out["large_steps"] = [m for m in steps if not (linear and m is linear[0])]
    return _metrics.clean(out)
