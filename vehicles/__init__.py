"""Digital twins: one folder per vehicle with ``vehicle.toml`` (physical parameters), ``README.md``
(where each number comes from) and ``gains/*.toml`` (published controller gain sets)."""

from __future__ import annotations

import hashlib
import re
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


def gains_dir(vehicle) -> Path:
    """The folder of a vehicle's gain sets: ``gains/`` beside its vehicle file.

    ``vehicle`` is a shipped name, a vehicle TOML path or folder, or a :class:`VehicleSpec` (its file). So a
    vehicle of one's own (``my-quad/vehicle.toml`` with ``my-quad/gains/*.toml``) has its gain sets exactly as a
    shipped one has; its name is never looked up among the shipped vehicles. One exception: a vehicle file with
    no ``gains/`` folder beside it whose ``[vehicle] name`` is a shipped vehicle is a modified copy of that
    vehicle (run.json records it as not the shipped file) and uses the shipped vehicle's gain sets.
    """
    if not isinstance(vehicle, VehicleSpec):
        vehicle = load_vehicle(vehicle)  # its [vehicle] name decides whether it is a modified shipped vehicle
    path, name = Path(vehicle.path), vehicle.name
    if not path.is_file():  # a spec built in memory: only a shipped name has gain sets
        path = VEHICLES_DIR / name / "vehicle.toml"
    own = path.parent / "gains"
    if own.is_dir() or not (VEHICLES_DIR / name / "gains").is_dir():
        return own
    return VEHICLES_DIR / name / "gains"


def _label(vehicle) -> str:
    return vehicle.name if isinstance(vehicle, VehicleSpec) else str(vehicle)


def list_gains(vehicle) -> list[str]:
    """Names of the gain sets of ``vehicle`` (see :func:`gains_dir`)."""
    return sorted(p.stem for p in gains_dir(vehicle).glob("*.toml"))


def gains_path(vehicle, name: str) -> Path:
    """The file of gain set ``name`` of ``vehicle`` (see :func:`gains_dir`).

    Raises
    ------
    rotorlab.errors.UnknownNameError
        No such set (listing the valid ones); ``name`` is never a path (``../x`` is refused the same way).
    """
    folder = gains_dir(vehicle)
    p = folder / f"{name}.toml"
    if not _SET_NAME.fullmatch(str(name)) or ".." in str(name) or not p.is_file():
        valid = list_gains(vehicle)
        if not valid:
            v = vehicle if isinstance(vehicle, VehicleSpec) else load_vehicle(vehicle)
            raise ConfigError(f"vehicle '{v.name}' ({v.path}) has no gain sets: no {folder}/*.toml",
                              field="gains", expected=f"--gains FILE.toml, or {folder / (str(name) + '.toml')}",
                              got=str(name))
        raise UnknownNameError(f"gain set of {_label(vehicle)}", str(name), valid)
    return p


_SET_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")


__all__ = ["G0", "RHO_AIR", "RigSpec", "RotorSpec", "VehicleSpec", "DEFAULT_VEHICLE", "VEHICLES_DIR", "list_vehicles",
           "load_vehicle", "parse_vehicle", "vehicle_path", "vehicle_provenance", "list_gains", "gains_path", "gains_dir"]
