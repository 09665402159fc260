"""``thrust-sweep``: static thrust-stand sweep of one rotor.

The rotor command steps through ``levels_pct`` (absolute %: blade pitch in units of the vehicle's
``blade_pitch_per_pct_rad`` for variable pitch, 100 b for variable RPM), each held ``hold_s``; the load cell
(thrust, drag torque) and the tachometer are logged. Metrics: the settled thrust, torque and speed of each level
and the static fits a test engineer makes from them: K_T in T = K_T Omega^2 (variable RPM) or the thrust slope
dT/d(blade pitch) (variable pitch).

Options
-------
``levels_pct`` : list of float   rotor command levels, % (default 20..100 in steps of 10)
``hold_s`` : float               time at each level, s
"""

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.sim.scenarios import Context, Setup, merged_options

NAME = "thrust-sweep"
DESCRIPTION = "thrust stand: static sweep of the rotor command (thrust, torque, speed)"
SCENES = ("thrust-stand",)
DURATION_S = 9.0
COLUMNS = {"cmd": "%", "thrust": "N", "torque": "N m", "omega": "rad/s"}
DEFAULTS = {"levels_pct": [20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0], "hold_s": 1.0}


def _levels(ctx: Context):
    o = merged_options(ctx, DEFAULTS)
    levels = np.asarray(o["levels_pct"], dtype=float)
    hold = float(o["hold_s"])
    if levels.ndim != 1 or levels.size < 2 or np.any(levels < 0) or np.any(levels > 100):
        raise ConfigError(field="options.levels_pct", expected="two or more levels in [0, 100] %", got=levels.tolist())
    if not hold > 0:
        raise ConfigError(field="options.hold_s", expected="> 0 s", got=hold)
    return levels, hold


def setup(ctx: Context) -> Setup:
    levels, hold = _levels(ctx)

    def drive(sim, t):
        k = min(int(t / hold + 1e-9), len(levels) - 1)
        sim.set_rotor_commands([levels[k]])
        thrust, torque = sim.load_cell()
        return {"cmd": levels[k], "thrust": thrust, "torque": torque, "omega": sim.rotor_speed_rad_s()[0]}

    return Setup(drive=drive, sensor_noise=False, extra_columns=dict(COLUMNS),
                 notes={"levels_pct": levels.tolist(), "hold_s": hold})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    levels, hold = _levels(ctx)
    t = log["t"]
    rows = []
    for k, lev in enumerate(levels):
        # the last 20 % of each hold: settled
        sel = (t >= (k + 0.8) * hold) & (t < (k + 1) * hold)
        if not sel.any():
            break
        rows.append((lev, float(np.mean(log["thrust"][sel])), float(np.mean(log["torque"][sel])),
                     float(np.mean(log["omega"][sel]))))
    cmd, thrust, torque, omega = (np.array(c) for c in zip(*rows))
    out = {"levels_pct": cmd.tolist(), "thrust_N": thrust.tolist(), "torque_Nm": torque.tolist(),
           "omega_rad_s": omega.tolist()}
    v = ctx.vehicle
    if v.kind == "variable-rpm":
        # least squares through the origin: T = K_T Omega^2
        out["k_thrust_N_per_rad2_s2"] = float(np.dot(omega**2, thrust) / np.dot(omega**2, omega**2))
    else:
        pitch = cmd * v.rotor.blade_pitch_per_pct_rad
        out["thrust_slope_N_per_rad"] = float(np.polyfit(pitch, thrust, 1)[0])
    return out
