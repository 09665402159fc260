"""Cascade attitude-controller gains: the TOML format the simulator reads and the tuner writes.

One table per loop::

    [pitch.outer]          # PD on angle -> rate set-point; angle in deg, rate in deg/s
    kp = 9.26
    kd = 1.11
    tf = 0.03              # derivative filter time constant, s
    b = 1.0                # proportional set-point weight (2-DoF), in [0, 1]
    c = 1.0                # derivative set-point weight (2-DoF), in [0, 1]

    [pitch.inner]          # PID on rate -> axis command in %
    kp = 0.257
    ki = 0.643
    kd = 0.0231
    tf = 0.0225

``roll`` reuses ``pitch`` by symmetry unless given; ``yaw`` is optional. ``b`` and ``c`` default to 1
(error-driven, one-degree-of-freedom PID) and ``ki`` of an outer PD must be 0.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from rotorlab import atomic
from rotorlab.config import read_toml
from rotorlab.errors import ConfigError

LOOPS = ("outer", "inner")
AXES = ("pitch", "roll", "yaw")


@dataclasses.dataclass(frozen=True)
class LoopGains:
    """Gains of one loop in parallel form: ``u = kp (b r - y) + ki/s (r - y) + kd s/(tf s + 1) (c r - y)``."""

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    tf: float = 0.0
    b: float = 1.0
    c: float = 1.0

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class AxisGains:
    outer: LoopGains
    inner: LoopGains


@dataclasses.dataclass(frozen=True)
class GainSet:
    """Gains of every axis; ``axes`` always holds ``pitch`` and ``roll`` (and ``yaw`` when given)."""

    name: str
    axes: dict

    def __getitem__(self, axis: str) -> AxisGains:
        try:
            return self.axes[axis]
        except KeyError:
            raise ConfigError(f"gain set '{self.name}' has no '{axis}' axis; it has {sorted(self.axes)}") from None

    def to_toml(self) -> str:
        lines = [f"# rotorlab gain set '{self.name}'"]
        for axis, g in self.axes.items():
            for loop in LOOPS:
                lines.append(f"\n[{axis}.{loop}]")
                for k, v in getattr(g, loop).as_dict().items():
                    lines.append(f"{k} = {float(v)!r}")
        return "\n".join(lines) + "\n"


def _num(src, field, value, *, lo=None, hi=None, lo_open=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(file=src, field=field, expected="a finite number", got=value)
    value = float(value)
    if lo is not None and (value < lo or (lo_open and value == lo)):
        rng = f"{'>' if lo_open else '>='} {lo}" + (f" and <= {hi}" if hi is not None else "")
        raise ConfigError(file=src, field=field, expected=f"a value {rng}", got=value)
    if hi is not None and value > hi:
        raise ConfigError(file=src, field=field, expected=f"a value in [{lo}, {hi}]", got=value)
    return value


def _loop(src, prefix, table, *, outer: bool) -> LoopGains:
    if not isinstance(table, dict):
        raise ConfigError(file=src, field=prefix, expected="a table", got=table)
    known = {f.name for f in dataclasses.fields(LoopGains)}
    unknown = set(table) - known
    if unknown:
        raise ConfigError(file=src, field=f"{prefix}.{sorted(unknown)[0]}", expected=f"one of {sorted(known)}",
                          got=sorted(unknown)[0])
    if "kp" not in table:
        raise ConfigError("missing gain", file=src, field=f"{prefix}.kp", expected="a number")
    vals = {
        "kp": _num(src, f"{prefix}.kp", table["kp"]),
        "ki": _num(src, f"{prefix}.ki", table.get("ki", 0.0), lo=0.0),
        "kd": _num(src, f"{prefix}.kd", table.get("kd", 0.0)),
        "tf": _num(src, f"{prefix}.tf", table.get("tf", 0.0), lo=0.0),
        "b": _num(src, f"{prefix}.b", table.get("b", 1.0), lo=0.0, hi=1.0),
        "c": _num(src, f"{prefix}.c", table.get("c", 1.0), lo=0.0, hi=1.0),
    }
    if outer and vals["ki"] != 0.0:
        raise ConfigError("the outer loop is a PD", file=src, field=f"{prefix}.ki", expected="0", got=vals["ki"])
    if vals["kd"] != 0.0 and vals["tf"] <= 0.0:
        raise ConfigError("a derivative term needs a filter", file=src, field=f"{prefix}.tf",
                          expected="tf > 0 s when kd != 0", got=vals["tf"])
    return LoopGains(**vals)


def parse_gains(data: dict, name: str = "custom", src="<gains>") -> GainSet:
    """Validate a parsed TOML mapping into a :class:`GainSet`; errors name the file and field."""
    if not isinstance(data, dict) or "pitch" not in data:
        raise ConfigError("missing axis", file=src, field="pitch", expected="tables [pitch.outer] and [pitch.inner]",
                          got=sorted(data) if isinstance(data, dict) else data)
    unknown = set(data) - set(AXES)
    if unknown:
        raise ConfigError(file=src, field=sorted(unknown)[0], expected=f"one of {list(AXES)}", got=sorted(unknown)[0])
    axes = {}
    for axis in AXES:
        if axis not in data:
            continue
        table = data[axis]
        if not isinstance(table, dict):
            raise ConfigError(file=src, field=axis, expected="a table", got=table)
        for loop in LOOPS:
            if loop not in table:
                raise ConfigError("missing loop", file=src, field=f"{axis}.{loop}",
                                  expected=f"a [{axis}.{loop}] table", got=sorted(table))
        extra = set(table) - set(LOOPS)
        if extra:
            raise ConfigError(file=src, field=f"{axis}.{sorted(extra)[0]}", expected="'outer' or 'inner'",
                              got=sorted(extra)[0])
        axes[axis] = AxisGains(
            outer=_loop(src, f"{axis}.outer", table["outer"], outer=True),
            inner=_loop(src, f"{axis}.inner", table["inner"], outer=False),
        )
    axes.setdefault("roll", axes["pitch"])
    return GainSet(name=name, axes=axes)


def load_gains(path) -> GainSet:
    """Read a gains TOML file."""
    path = Path(path)
    return parse_gains(read_toml(path, "gains"), name=path.stem, src=path)


def save_gains(gains: GainSet, path) -> Path:
    """Write ``gains`` atomically as TOML that :func:`load_gains` reads back identically."""
    return atomic.write_text(path, gains.to_toml())
