"""Domain randomisation: the one definition of how the twin's parameters are drawn, used by the gym envs
(``randomize=``), ``rotorlab montecarlo`` (``--vary``) and the batched runner (``run_batch(vary=...)``).

Spreads (``dict`` parameter -> spread) and the distribution each draws from, in this draw order (a parameter
without a spread, or with spread 0, consumes no random numbers):

``mass``
    the airframe mass times a factor uniform in ``[1 - s, 1 + s]`` (``0 <= s < 1``).
``inertia``
    each principal inertia times its own factor uniform in ``[1 - s, 1 + s]``.

    The mass and inertia draws are kept physical: a (mass, inertia) candidate whose vehicle would have no rigid
    airframe body (:func:`rotorlab.vehicles.bodies.unphysical`: the whole vehicle's moments less the rotor
    discs' share breaking ``A + B >= C``, or a mass or moment <= 0) is redrawn, so the draw is uniform over the
    physical part of the box; :attr:`Draw.rejected_bodies` counts the candidates redrawn.
``motor_lag``
    every rotor's servo/motor time constant times one factor uniform in ``[1 - s, 1 + s]``.
``delay_s``
    the transport delay, a whole number of physics steps uniform over ``[low, high]`` s (MuJoCo's actuator
    history buffer realises it): a pair ``(low, high)``, or a number ``s`` for ``[delay, delay + s]`` above the
    vehicle's own delay. Never beyond the vehicle file's bound on a delay
    (:data:`rotorlab.vehicles.spec.MAX_LAG_DELAY_S`): a step drawn above it is redrawn once, uniform over the
    steps within the bound (which makes the draw uniform over ``[low, min(high, bound)]``), and
    :attr:`Draw.rejected_delay` says so.
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
from rotorlab.vehicles.bodies import unphysical
from rotorlab.vehicles.spec import MAX_LAG_DELAY_S

#: every randomisable parameter, in draw order
KEYS = ("mass", "inertia", "motor_lag", "delay_s", "imu_mount", "wind")
_RELATIVE = ("mass", "inertia", "motor_lag", "imu_mount")
#: a redraw budget for a rigid airframe body (spreads below ~0.5 need one or two draws)
_BODY_TRIES = 100


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
    #: (mass, inertia) candidates redrawn because their airframe body was no rigid body
    rejected_bodies: int = 0
    #: 1 when the delay was drawn above the vehicle file's bound and redrawn within it, else 0
    rejected_delay: int = 0

    def as_dict(self) -> dict:
        """Flat numbers for tables (Monte Carlo Parquet rows; their units in :data:`DRAW_UNITS`)."""
        a, b, c = self.inertia_factors
        return {"mass_factor": self.mass_factor, "inertia_factor_x": a, "inertia_factor_y": b,
                "inertia_factor_z": c, "lag_factor": self.lag_factor,
                "delay_s": math.nan if self.delay_s is None else self.delay_s,
                "imu_mount_factor": self.imu_mount_factor, "wind_speed_mps": self.wind_speed_mps,
                "wind_from_deg": self.wind_from_deg, "rejected_bodies": self.rejected_bodies,
                "rejected_delay": self.rejected_delay}


#: units of :meth:`Draw.as_dict`'s columns
DRAW_UNITS = {"mass_factor": "1", "inertia_factor_x": "1", "inertia_factor_y": "1", "inertia_factor_z": "1",
              "lag_factor": "1", "delay_s": "s", "imu_mount_factor": "1", "wind_speed_mps": "m/s",
              "wind_from_deg": "deg", "rejected_bodies": "1", "rejected_delay": "1"}


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

    rejected_bodies = 0
    while True:
        mass = factor("mass")
        inertia = tuple(factor("inertia") for _ in range(3))
        if (mass, inertia) == (1.0, (1.0, 1.0, 1.0)) or not unphysical(apply(vehicle, Draw(mass, inertia))):
            break
        rejected_bodies += 1
        if rejected_bodies == _BODY_TRIES:
            raise ConfigError(field=f"{field}.inertia", expected="spreads that leave a rigid airframe body "
                              f"(A + B >= C) within {_BODY_TRIES} draws",
                              got={k: sp[k] for k in ("mass", "inertia") if k in sp})
    lag = factor("motor_lag")
    delay = None
    rejected_delay = 0
    if "delay_s" in sp:
        s = sp["delay_s"]
        d0 = max(vehicle.rotor.delay_s)
        lo, hi = s if isinstance(s, tuple) else (d0, d0 + s)
        k_lo, k_hi = round(lo / physics_dt_s), round(hi / physics_dt_s)
        k_max = min(k_hi, math.floor(MAX_LAG_DELAY_S / physics_dt_s + 1e-9))
        k = int(rng.integers(k_lo, k_hi + 1))
        if k > k_max:
            k, rejected_delay = int(rng.integers(k_lo, k_max + 1)), 1
        delay = k * physics_dt_s
    imu_mount = factor("imu_mount")
    speed = from_deg = 0.0
    if sp.get("wind"):
        speed = float(rng.uniform(0.0, sp["wind"]))
        from_deg = float(rng.uniform(0.0, 360.0))
    return Draw(mass, inertia, lag, delay, imu_mount, speed, from_deg, rejected_bodies, rejected_delay)


def apply(vehicle, d: Draw):
    """The vehicle spec with a draw's physical parameters (the wind is the scenario's, not the vehicle's)."""
    rotor = dataclasses.replace(vehicle.rotor, lag_s=tuple(t * d.lag_factor for t in vehicle.rotor.lag_s),
                                delay_s=vehicle.rotor.delay_s if d.delay_s is None
                                else (d.delay_s,) * len(vehicle.rotor.delay_s))
    imu = dataclasses.replace(vehicle.imu, mount_frequency_hz=vehicle.imu.mount_frequency_hz * d.imu_mount_factor)
    return dataclasses.replace(vehicle, mass_kg=vehicle.mass_kg * d.mass_factor, rotor=rotor, imu=imu,
                               inertia_kgm2=tuple(j * f for j, f in zip(vehicle.inertia_kgm2, d.inertia_factors)))


__all__ = ["KEYS", "Draw", "check_spreads", "draw", "apply"]
