"""Scenarios: one module per scenario, registered here by name.

A scenario module defines ``NAME``, ``DESCRIPTION``, ``SCENES`` (the scenes it can run in; the first is
the default), ``DURATION_S`` and ``setup(ctx) -> Setup``. The runner (``rotorlab.sim.runner``) builds the
simulator and the flight software from the :class:`Setup`, runs it, logs it and scores it with the
scenario's ``metrics(log, ctx)`` function if the module has one.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from collections.abc import Callable
from typing import Any

from rotorlab.config import did_you_mean
from rotorlab.errors import ConfigError, UnknownNameError

# scenario name -> module under rotorlab.sim.scenarios
SCENARIOS = {
    "rest": "rest",
    "setpoint": "setpoint",
    "gust": "gust",
    "input-disturbance": "input_disturbance",
    "rope-pull": "rope_pull",
    "hover": "hover",
    "prbs": "prbs",
    "prbs-closed": "prbs_closed",
    "prbs-periodic": "prbs_periodic",
    "prbs-flight": "prbs_flight",
    "thrust-sweep": "thrust_sweep",
    "thrust-steps": "thrust_steps",
    "autopilot-sysid": "autopilot_sysid",
}


@dataclasses.dataclass
class Context:
    """What a scenario's setup gets: the chosen vehicle, scene, gains and options."""

    vehicle: Any  # VehicleSpec
    scene: str
    gains: Any  # GainSet or None
    seed: int
    duration_s: float
    options: dict
    dt_s: float = 0.02  # flight-software period of the vehicle (VehicleSpec.control_dt_s): one sample per tick


@dataclasses.dataclass
class Setup:
    """What the runner needs to run a scenario.

    ``mode``/``reference``/``excitation``/``schedule``/``altitude_hold`` configure the flight software
    (:class:`~rotorlab.sim.control.flight_software.FlightSoftware`); ``disturbances`` are
    composed into the physics; ``sensor_noise`` switches the IMU noise; ``u_limit_pct`` and
    ``rate_limit_dps`` override the vehicle's roll/pitch saturations (its ``[commands]``) where a test used other
    values (None: the vehicle's; :meth:`limits`); ``extra_columns`` name scenario-specific log columns
    (name -> unit) filled by ``on_tick(sim, fs_out) -> dict``. A bench scenario (thrust stand) sets
    ``drive(sim, t) -> dict`` instead: it commands the rotor itself and returns the extra columns.
    """

    mode: str = "cascade"
    reference: Callable | None = None
    altitude_hold: bool = False
    excitation: dict = dataclasses.field(default_factory=dict)
    schedule: list = dataclasses.field(default_factory=list)
    disturbances: list = dataclasses.field(default_factory=list)
    sensor_noise: bool = True
    u_limit_pct: float | None = None
    rate_limit_dps: float | None = None
    open_loop_axes: tuple = ("roll", "pitch", "yaw")
    extra_columns: dict = dataclasses.field(default_factory=dict)
    on_tick: Callable | None = None
    noise_on: Callable | None = None  # noise_on(t) -> bool: when the requested IMU noise is on (default always)
    drive: Callable | None = None  # drive(sim, t) -> dict of extra columns; replaces the flight software (bench tests)
    notes: dict = dataclasses.field(default_factory=dict)
    #: discrete controllers (ControllerSpec) the scenario flies in place of the cascade, e.g. the known PD of a
    #: closed-loop identification; a controller given to the run replaces them
    controller: list = dataclasses.field(default_factory=list)
    #: ``rate_excitation(t) -> (p, q, r)`` deg/s added to an autopilot's rate set-point (PX4 autotune, ArduCopter
    #: SYSID); a run of such a set-up must fly an autopilot's laws (``--controller px4:...``/``ardupilot:...``)
    rate_excitation: Callable | None = None


    def limits(self, vehicle):
        """The flight software's saturations in this scenario: the vehicle's, with this set-up's overrides."""
        over = {k: v for k, v in (("limit_pct", self.u_limit_pct), ("rate_limit_dps", self.rate_limit_dps))
                if v is not None}
        return dataclasses.replace(vehicle.commands, **over) if over else vehicle.commands


#: largest magnitude of a number in a scenario option (degrees, m/s, s, ...): wind_mps = 1e300 overflowed the
#: turbulence filter's covariance into a traceback; beyond 1e6 no option means a flyable case
MAX_OPTION_MAGNITUDE = 1e6


def merged_options(ctx: Context, defaults: dict) -> dict:
    """The scenario's options over its defaults.

    An unknown option is an error naming it and the valid ones; a given option must have its default's type
    (a number where the default is a number, a list of numbers where it is such a list), and no number may be NaN,
    infinite or of magnitude above :data:`MAX_OPTION_MAGNITUDE`.
    """
    unknown = sorted(set(ctx.options) - set(defaults))
    if unknown:
        raise ConfigError(field=f"options.{unknown[0]}", expected=f"one of {sorted(defaults)}", got=unknown[0],
                          hint=did_you_mean(unknown[0], sorted(defaults)))

    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    for key, val in ctx.options.items():
        d = defaults[key]
        items = val if isinstance(val, (list, tuple)) else [val]
        if any(number(x) and not math.isfinite(x) for x in items):
            raise ConfigError(field=f"options.{key}", expected="finite numbers", got=val)
        if any(number(x) and abs(x) > MAX_OPTION_MAGNITUDE for x in items):
            raise ConfigError("implausible option value", field=f"options.{key}",
                              expected=f"numbers of magnitude at most {MAX_OPTION_MAGNITUDE:g}", got=val)
        if isinstance(d, bool):
            ok, want = isinstance(val, bool), "true or false"
        elif number(d):
            ok, want = number(val), "a number"
        elif isinstance(d, (list, tuple)) and all(number(x) for x in d):
            ok, want = isinstance(val, (list, tuple)) and all(number(x) for x in val), "a list of numbers"
        else:  # a name or None: the scenario checks the value itself
            ok, want = True, ""
        if not ok:
            raise ConfigError(field=f"options.{key}", expected=want, got=val)
    return {**defaults, **ctx.options}


def list_scenarios() -> list[str]:
    return sorted(SCENARIOS)


def get(name: str):
    if name not in SCENARIOS:
        raise UnknownNameError("scenario", name, SCENARIOS)
    return importlib.import_module(f"rotorlab.sim.scenarios.{SCENARIOS[name]}")


def get_with_scene(name: str, scene: str | None):
    """Scenario module ``name`` and the scene a run of it takes place in: ``scene``, or the scenario's first (its
    default); a ConfigError naming the scenario's scenes when it does not run in ``scene``."""
    mod = get(name)
    scene = scene or mod.SCENES[0]
    if scene not in mod.SCENES:
        raise ConfigError(f"scenario '{name}' runs in {list(mod.SCENES)}", field="scene", expected=list(mod.SCENES),
                          got=scene)
    return mod, scene
