"""Domain randomisation: the one definition of how the twin's parameters are drawn, used by the gym envs
(``randomize=``), ``rotorlab montecarlo`` (``--vary``) and the batched runner (``run_batch(vary=...)``).

Spreads (``dict`` parameter -> spread) and the distribution each draws from, in this draw order (a parameter
without a spread, or with spread 0, consumes no random numbers):

``mass``
    the airframe mass times a factor uniform in ``[1 - s, 1 + s]`` (``0 <= s < 1``).
``inertia``
    each principal inertia times its own factor uniform in ``[1 - s, 1 + s]``; a draw that breaks the triangle
    inequality ``A + B >= C`` (no rigid body has it) is redrawn, so the draw is uniform over the feasible box.
``motor_lag``
    every rotor's servo/motor time constant times one factor uniform in ``[1 - s, 1 + s]``.
``delay_s``
    the transport delay, a whole number of physics steps uniform over ``[low, high]`` s (MuJoCo's actuator
    history buffer realises it): a pair ``(low, high)``, or a number ``s`` for ``[delay, delay + s]`` above the
    vehicle's own delay.
``imu_mount``
    the IMU mount's natural frequency times a factor uniform in ``[1 - s, 1 + s]``.
``wind``
    a steady horizontal wind: speed uniform in ``[0, s]`` m/s, coming from a direction uniform in ``[0, 360)``
    deg (scenarios whose wind has its own direction use the speed alone).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.vehicles.spec import MAX_LAG_DELAY_S

#: every randomisable parameter, in draw order
KEYS = ("mass", "inertia", "motor_lag", "delay_s", "imu_mount", "wind")
_RELATIVE = ("mass", "inertia", "motor_lag", "imu_mount")
#: a redraw budget for the inertia triangle inequality (spreads below ~0.5 need one or two draws)
_INERTIA_TRIES = 100


@dataclasses.dataclass(frozen=True)
class Draw:
    """One draw: the factors and values :func:`apply` puts into a vehicle (1 / None: unchanged)."""

    mass_factor: float = 1.0
    inertia_factors: tuple = (1.0, 1.0, 1.0)
    lag_factor: float = 1.0
    delay_s: float | None = None
    imu_mount_factor: float = 1.0
    wind_speed_mps: float = 0.0
    wind_from_deg: float = 0.0

    def as_dict(self) -> dict:
        """Flat numbers for tables (Monte Carlo Parquet rows; their units in :data:`DRAW_UNITS`)."""
        a, b, c = self.inertia_factors
        return {"mass_factor": self.mass_factor, "inertia_factor_x": a, "inertia_factor_y": b,
                "inertia_factor_z": c, "lag_factor": self.lag_factor,
                "delay_s": math.nan if self.delay_s is None else self.delay_s,
                "imu_mount_factor": self.imu_mount_factor, "wind_speed_mps": self.wind_speed_mps,
                "wind_from_deg": self.wind_from_deg}


#: units of :meth:`Draw.as_dict`'s columns
DRAW_UNITS = {"mass_factor": "1", "inertia_factor_x": "1", "inertia_factor_y": "1", "inertia_factor_z": "1",
              "lag_factor": "1", "delay_s": "s", "imu_mount_factor": "1", "wind_speed_mps": "m/s",
              "wind_from_deg": "deg"}


def check_spreads(spreads: dict, keys=KEYS, field: str = "randomize") -> dict:
    """Validated spreads; ``keys`` restricts the parameters a caller supports (unknown: error listing them)."""
    out = {}
    for k, s in dict(spreads or {}).items():
        if k not in keys:
            raise UnknownNameError(f"{field} parameter", k, keys)
        if k == "delay_s" and not np.isscalar(s):
            out[k] = _range(s, f"{field}.{k}")
            continue
        if isinstance(s, bool) or not isinstance(s, (int, float, np.floating, np.integer)) or not math.isfinite(s):
            raise ConfigError(field=f"{field}.{k}", expected="a number", got=s)
        if k in _RELATIVE and not 0.0 <= s < 1.0:
            raise ConfigError(field=f"{field}.{k}", expected="a relative spread in [0, 1)", got=s)
        if not s >= 0.0:
            raise ConfigError(field=f"{field}.{k}", expected="a spread >= 0", got=s)
        out[k] = float(s)
    return out


def _range(val, field):
    try:
        lo, hi = (float(x) for x in val)
    except (TypeError, ValueError):
        raise ConfigError(field=field, expected="a (low, high) pair", got=val) from None
    # the vehicle file's own bound on a delay: (10, 20) s was accepted and built a 20 000-step delay buffer
    if not 0.0 <= lo <= hi <= MAX_LAG_DELAY_S:
        raise ConfigError(field=field, expected=f"0 <= low <= high <= {MAX_LAG_DELAY_S} s", got=val)
    return lo, hi


def draw(vehicle, spreads: dict, rng: np.random.Generator, physics_dt_s: float, keys=KEYS,
         field: str = "randomize") -> Draw:
    """One seeded draw of the parameters in ``spreads`` (module docstring) for ``vehicle``."""
    sp = check_spreads(spreads, keys, field)

    def factor(name):
        s = sp.get(name, 0.0)
        return float(rng.uniform(1.0 - s, 1.0 + s)) if s else 1.0

    mass = factor("mass")
    for _ in range(_INERTIA_TRIES):
        inertia = tuple(factor("inertia") for _ in range(3))
        a, b, c = sorted(j * f for j, f in zip(vehicle.inertia_kgm2, inertia))
        if a + b >= c:
            break
    else:
        raise ConfigError(field=f"{field}.inertia", expected="a spread that keeps A + B >= C", got=sp["inertia"])
    lag = factor("motor_lag")
    delay = None
    if "delay_s" in sp:
        s = sp["delay_s"]
        d0 = max(vehicle.rotor.delay_s)
        lo, hi = s if isinstance(s, tuple) else (d0, d0 + s)
        delay = int(rng.integers(round(lo / physics_dt_s), round(hi / physics_dt_s) + 1)) * physics_dt_s
    imu_mount = factor("imu_mount")
    speed = from_deg = 0.0
    if sp.get("wind"):
        speed = float(rng.uniform(0.0, sp["wind"]))
        from_deg = float(rng.uniform(0.0, 360.0))
    return Draw(mass, inertia, lag, delay, imu_mount, speed, from_deg)


def apply(vehicle, d: Draw):
    """The vehicle spec with a draw's physical parameters (the wind is the scenario's, not the vehicle's)."""
    rotor = dataclasses.replace(vehicle.rotor, lag_s=tuple(t * d.lag_factor for t in vehicle.rotor.lag_s),
                                delay_s=vehicle.rotor.delay_s if d.delay_s is None
                                else (d.delay_s,) * len(vehicle.rotor.delay_s))
    imu = dataclasses.replace(vehicle.imu, mount_frequency_hz=vehicle.imu.mount_frequency_hz * d.imu_mount_factor)
    return dataclasses.replace(vehicle, mass_kg=vehicle.mass_kg * d.mass_factor, rotor=rotor, imu=imu,
                               inertia_kgm2=tuple(j * f for j, f in zip(vehicle.inertia_kgm2, d.inertia_factors)))


__all__ = ["KEYS", "Draw", "check_spreads", "draw", "apply"]
