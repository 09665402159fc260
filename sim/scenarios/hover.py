"""``hover``: the A2-MINI/B flight test (reference 000): hover out of ground effect at 5 m, mean wind 2.5 m/s
with Dryden turbulence, position hold on x, y, z, no pilot input, and the attitude gains switched in flight
(standard -> optimal) at ``switch_s``.

Options
-------
``wind_mps`` : float        mean wind (default 2.5)
``from_deg`` : float        where it comes from (default 0: headwind, the pitch axis holds the position)
``turbulence`` : bool       Dryden turbulence on (default True)
``switch_s`` : float/None   time of the gain switch (default: mid-run; None or "none": no switch)
``switch_to`` : str         gain set of the vehicle switched to (default ``optimal``, else ``optimal-flight``)
"""

from __future__ import annotations

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.gains import GainSet, load_gains
from rotorlab.scenes import HOVER_HEIGHT_M
from rotorlab.sim.disturbances.dryden_wind import DrydenWind
from rotorlab.sim.disturbances.mean_wind import MeanWind
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options
from rotorlab.vehicles import gains_path, list_gains

NAME = "hover"
DESCRIPTION = "hover at 5 m in 2.5 m/s wind with turbulence, position hold, in-flight gain switch"
SCENES = ("free-flight",)
DURATION_S = 40.0
DEFAULTS = {"wind_mps": 2.5, "from_deg": 0.0, "turbulence": True, "switch_s": "mid", "switch_to": None}


def _switch_gains(vehicle, name) -> GainSet:
    if isinstance(name, GainSet):
        return name
    names = [name] if name else ["optimal", "optimal-flight"]
    for n in names:
        try:
            return load_gains(gains_path(vehicle, n))
        except (UnknownNameError, ConfigError):  # no such set, or a vehicle file with no gain sets at all
            continue
    valid = list_gains(vehicle)
    if not valid:
        raise ConfigError(f"the hover scenario switches gain sets in flight, and vehicle '{vehicle.name}' has none "
                          f"beside its file ({vehicle.path})", field="options.switch_to",
                          expected="a gain set in gains/NAME.toml beside the vehicle file", got=name)
    raise UnknownNameError(f"gain set of {vehicle.name} to switch to", str(name or "optimal"), valid)


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    dist = [MeanWind(o["wind_mps"], o["from_deg"])] if o["wind_mps"] else []
    if o["turbulence"]:
        if not o["wind_mps"] > 0:
            raise ConfigError("Dryden turbulence is advected by the mean wind", field="options.wind_mps",
                              expected="> 0 m/s with turbulence on", got=o["wind_mps"])
        dist.append(DrydenWind(o["wind_mps"], HOVER_HEIGHT_M, ctx.duration_s, o["from_deg"]))
    t_sw = {"mid": ctx.duration_s / 2, "none": None}.get(o["switch_s"], o["switch_s"])
    if t_sw is not None and (isinstance(t_sw, (str, bool)) or not isinstance(t_sw, (int, float))):
        # a TOML option value cannot be None: the CLI says "none" (a vehicle without an optimal gain set)
        raise ConfigError("the gain switch time", field="options.switch_s",
                          expected='"mid", "none" (no switch) or a time in s', got=t_sw)
    schedule = [(float(t_sw), _switch_gains(ctx.vehicle, o["switch_to"]))] if t_sw is not None else []
    return Setup(mode="position", disturbances=dist, schedule=schedule,
                 notes={"switch_s": t_sw, "switch_to": schedule[0][1].name if schedule else None})


def metrics(log, ctx: Context, setup: Setup) -> dict:
    lim = setup.u_limit_pct or ctx.vehicle.command_limit_pct
    t_sw = setup.notes["switch_s"]
    settle = 3.0  # s left out after the start and after the switch
    phases = {"all": (settle, float("inf"))} if t_sw is None else {
        "before_switch": (settle, t_sw), "after_switch": (t_sw + settle, float("inf"))}
    out = {}
    for name, (a, b) in phases.items():
        m = _metrics.window(log, a, b)
        if m.sum() < 8:
            continue
        ph = {}
        for axis, (angle, _, cmd) in _metrics.AXIS_CHANNELS.items():
            err = log[angle][m] - log[f"{angle}_ref"][m]
            ph[axis] = {"mean_ref_deg": float(log[f"{angle}_ref"][m].mean()), "rms_error_deg": float((err ** 2).mean() ** 0.5),
                        "control": _metrics.control(log, cmd, lim, a, b)}
        pos = ((log["x"][m] - log["x_ref"][m]) ** 2 + (log["y"][m] - log["y_ref"][m]) ** 2) ** 0.5
        ph["position_error_rms_m"] = float((pos ** 2).mean() ** 0.5)
        ph["altitude_error_rms_m"] = float(((log["z"][m] - log["z_ref"][m]) ** 2).mean() ** 0.5)
        out[name] = ph
    return _metrics.clean(out)
