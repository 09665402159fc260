"""``thrust-steps``: throttle (or collective) steps on the thrust stand: the first-order motor/servo response.

The command alternates between ``low_pct`` and ``high_pct`` every ``hold_s``; the load cell is logged at the
50 Hz tick like a bench data logger. Metrics: a first-order-plus-delay model fitted to each step by least
squares (time constant and delay); with 20 ms samples a lag much shorter than 20 ms (the P2-A2's 5 ms servo)
is not resolved, which the fit reports as a time constant near zero.

Options
-------
``low_pct`` : float    low command level, %
``high_pct`` : float   high command level, %
``hold_s`` : float     time at each level, s
"""

import numpy as np
import scipy.optimize as so

from rotorlab.errors import ConfigError
from rotorlab.sim.scenarios import Context, Setup, merged_options

NAME = "thrust-steps"
DESCRIPTION = "thrust stand: command steps, first-order motor/servo response and delay"
SCENES = ("thrust-stand",)
DURATION_S = 2.0
DEFAULTS = {"low_pct": 50.0, "high_pct": 70.0, "hold_s": 0.5}
COLUMNS = {"cmd": "%", "thrust": "N", "omega": "rad/s"}


def _opts(ctx):
    o = merged_options(ctx, DEFAULTS)
    lo, hi, hold = float(o["low_pct"]), float(o["high_pct"]), float(o["hold_s"])
    if not (0 <= lo < hi <= 100):
        raise ConfigError(field="options.low_pct/high_pct", expected="0 <= low < high <= 100", got=(lo, hi))
    return lo, hi, hold


def setup(ctx: Context) -> Setup:
    lo, hi, hold = _opts(ctx)

    def drive(sim, t):
        cmd = hi if int(t / hold + 1e-9) % 2 else lo
        sim.set_rotor_commands([cmd])
        return {"cmd": cmd, "thrust": sim.load_cell()[0], "omega": sim.rotor_speed_rad_s()[0]}

    return Setup(drive=drive, sensor_noise=False, extra_columns=dict(COLUMNS))


def _fit_step(ts, ys):
    """First-order-plus-delay fit y = y0 + (y1 - y0) (1 - exp(-(t - d)/tau)) for t > d."""
    y0, y1 = ys[0], ys[-1]

    def model(x):
        tau, d = x
        r = np.clip(ts - d, 0.0, None)
        return y0 + (y1 - y0) * (1 - np.exp(-r / max(tau, 1e-6)))

    best = min((so.least_squares(lambda x: model(x) - ys, [tau0, d0], bounds=([1e-4, 0.0], [1.0, 0.5]))
                for tau0 in (0.01, 0.05) for d0 in (0.02, 0.06)), key=lambda s: s.cost)
    return float(best.x[0]), float(best.x[1])


def metrics(log, ctx: Context, setup: Setup) -> dict:
    lo, hi, hold = _opts(ctx)
    t, y = log["t"], log["thrust"]
    dt = float(t[1] - t[0])
    taus, delays = [], []
    k = 1
    while (k + 1) * hold <= t[-1] + dt + 1e-9:
        sel = (t >= k * hold - 1e-9) & (t < (k + 1) * hold - 1e-9)
        # the sample at the step tick is still the old level (the command acts from that tick on)
        tau, d = _fit_step(t[sel] - k * hold, y[sel])
        taus.append(tau)
        delays.append(d)
        k += 1
    return {"step_time_constant_s": taus, "step_delay_s": delays,
            "time_constant_s": float(np.median(taus)) if taus else None,
            "delay_s": float(np.median(delays)) if delays else None}
