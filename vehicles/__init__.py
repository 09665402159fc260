"""Digital twins: one folder per vehicle with ``vehicle.toml`` (physical parameters), ``README.md``
(where each number comes from) and ``gains/*.toml`` (published controller gain sets)."""

from __future__ import annotations

from pathlib import Path

from rotorlab.errors import UnknownNameError

from .spec import G0, RHO_AIR, RigSpec, RotorSpec, VehicleSpec, load_vehicle_file, parse_vehicle

VEHICLES_DIR = Path(__file__).resolve().parent
DEFAULT_VEHICLE = "anteos-p2a2"


def list_vehicles() -> list[str]:
    return sorted(p.parent.name for p in VEHICLES_DIR.glob("*/vehicle.toml"))


def vehicle_path(name_or_path) -> Path:
    p = Path(name_or_path)
    if p.suffix == ".toml" and p.exists():
        return p
    if (VEHICLES_DIR / str(name_or_path) / "vehicle.toml").exists():
        return VEHICLES_DIR / str(name_or_path) / "vehicle.toml"
    raise UnknownNameError("vehicle", str(name_or_path), list_vehicles())


def load_vehicle(name_or_path, physics_dt_s: float | None = None) -> VehicleSpec:
    """Load a shipped vehicle by name, or a vehicle TOML by path."""
    return load_vehicle_file(vehicle_path(name_or_path), physics_dt_s)


def list_gains(vehicle: str) -> list[str]:
    return sorted(p.stem for p in (vehicle_path(vehicle).parent / "gains").glob("*.toml"))


def gains_path(vehicle: str, name: str) -> Path:
    p = vehicle_path(vehicle).parent / "gains" / f"{name}.toml"
    if not p.exists():
        raise UnknownNameError(f"gain set of {vehicle}", name, list_gains(vehicle))
    return p


__all__ = ["G0", "RHO_AIR", "RigSpec", "RotorSpec", "VehicleSpec", "DEFAULT_VEHICLE", "VEHICLES_DIR", "list_vehicles",
           "load_vehicle", "parse_vehicle", "vehicle_path", "list_gains", "gains_path"]
