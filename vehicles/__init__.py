"""Digital twins: one folder per vehicle with ``vehicle.toml`` (physical parameters), ``README.md``
(where each number comes from) and ``gains/*.toml`` (published controller gain sets)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from rotorlab.errors import ConfigError, UnknownNameError

from .bodies import unphysical
from .spec import G0, RHO_AIR, RigSpec, RotorSpec, VehicleSpec, load_vehicle_file, parse_vehicle

VEHICLES_DIR = Path(__file__).resolve().parent
DEFAULT_VEHICLE = "anteos-p2a2"


def list_vehicles() -> list[str]:
    return sorted(p.parent.name for p in VEHICLES_DIR.glob("*/vehicle.toml"))


def vehicle_path(name_or_path) -> Path:
    """The vehicle TOML of a shipped vehicle name, a vehicle TOML path, or a vehicle folder (relative or absolute)
    holding ``vehicle.toml``."""
    p = Path(name_or_path)
    if p.suffix == ".toml" and p.exists():
        return p
    if p.is_dir() and (p / "vehicle.toml").is_file():
        return p / "vehicle.toml"
    if (VEHICLES_DIR / str(name_or_path) / "vehicle.toml").exists():
        return VEHICLES_DIR / str(name_or_path) / "vehicle.toml"
    if p.suffix == ".toml":
        raise ConfigError("vehicle file not found", file=p)
    raise UnknownNameError("vehicle", str(name_or_path), list_vehicles())


def vehicle_provenance(v: VehicleSpec) -> dict:
    """Where a vehicle came from, for run.json: its name, file (absolute), the file's SHA-256 and whether it is
    the shipped file unmodified (a modified copy keeps the shipped name but not the hash)."""
    path = Path(v.path)
    if not path.is_file():
        return {"name": v.name, "path": None, "sha256": None, "shipped": False}
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    shipped = VEHICLES_DIR / v.name / "vehicle.toml"
    same = shipped.is_file() and hashlib.sha256(shipped.read_bytes()).hexdigest() == digest
    return {"name": v.name, "path": str(path.resolve()), "sha256": digest, "shipped": same}


def load_vehicle(name_or_path, physics_dt_s: float | None = None) -> VehicleSpec:
    """Load a shipped vehicle by name, or a vehicle TOML by path.

    Raises
    ------
    rotorlab.errors.ConfigError
        Besides the file's own checks: an airframe body that is no rigid body once the IMU board and the rotor
        discs come off the whole vehicle's mass and inertia (:func:`rotorlab.vehicles.bodies.unphysical`).
    """
    v = load_vehicle_file(vehicle_path(name_or_path), physics_dt_s)
    bad = unphysical(v)
    if bad:
        raise ConfigError(bad[1], file=v.path, field=bad[0], expected="a whole-vehicle mass and inertia that leave the "
                          "airframe body (less the IMU board and the rotor discs) a rigid body",
                          got=list(v.inertia_kgm2) if bad[0].endswith("inertia_kgm2") else v.mass_kg)
    return v


def list_gains(vehicle: str) -> list[str]:
    return sorted(p.stem for p in (vehicle_path(vehicle).parent / "gains").glob("*.toml"))


def gains_path(vehicle: str, name: str) -> Path:
    p = vehicle_path(vehicle).parent / "gains" / f"{name}.toml"
    if not p.exists():
        raise UnknownNameError(f"gain set of {vehicle}", name, list_gains(vehicle))
    return p


__all__ = ["G0", "RHO_AIR", "RigSpec", "RotorSpec", "VehicleSpec", "DEFAULT_VEHICLE", "VEHICLES_DIR", "list_vehicles",
           "load_vehicle", "parse_vehicle", "vehicle_path", "vehicle_provenance", "list_gains", "gains_path"]
