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
from pathlib import Path

from rotorlab import atomic
from rotorlab.config import Table, read_toml
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


#: largest magnitude of a gain or filter constant (shipped sets: at most about 20): kp = 1e300 reached the tuner as
#: "the interconnection is not well posed" and the flight software as overflow
MAX_GAIN = 1e6


def _loop(t: Table, *, outer: bool) -> LoopGains:
    vals = {
        "kp": t.num("kp"),
        "ki": t.num("ki", 0.0, lo=0.0),
        "kd": t.num("kd", 0.0),
        "tf": t.num("tf", 0.0, lo=0.0),
        "b": t.num("b", 1.0, lo=0.0, hi=1.0),
        "c": t.num("c", 1.0, lo=0.0, hi=1.0),
    }
    if outer and vals["ki"] != 0.0:
        raise t.error("ki", "the outer loop is a PD", expected="0", got=vals["ki"])
    if vals["kd"] != 0.0 and vals["tf"] <= 0.0:
        raise t.error("tf", "a derivative term needs a filter", expected="tf > 0 s when kd != 0", got=vals["tf"])
    return LoopGains(**vals)


def parse_gains(data: dict, name: str = "custom", src="<gains>") -> GainSet:
    """Validate a parsed TOML mapping into a :class:`GainSet`; errors name the file and field."""
    top = Table(src, data, magnitude=(0.0, MAX_GAIN))
    if "pitch" not in top:
        raise top.error("pitch", "missing axis", expected="tables [pitch.outer] and [pitch.inner]", got=sorted(data))
    axes = {}
    for axis in AXES:
        t = top.table(axis, required=False)
        if t is None:
            continue
        axes[axis] = AxisGains(outer=_loop(t.table("outer"), outer=True), inner=_loop(t.table("inner"), outer=False))
    top.check_unknown()
    axes.setdefault("roll", axes["pitch"])
    return GainSet(name=name, axes=axes)


def load_gains(path) -> GainSet:
    """Read a gains TOML file."""
    path = Path(path)
    return parse_gains(read_toml(path, "gains"), name=path.stem, src=path)


def save_gains(gains: GainSet, path) -> Path:
    """Write ``gains`` atomically as TOML that :func:`load_gains` reads back identically."""
    return atomic.write_text(path, gains.to_toml())
