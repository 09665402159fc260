"""Autopilot parameter tables and parameter files: QGroundControl ``.params`` (PX4) and Mission Planner ``.parm``.

A parameter table lists, for every parameter a law reads, the autopilot's own name, unit, documented range,
default and the source the facts come from. Parameter values are always kept in the autopilot's names and
units; the laws convert (deg/s to rad/s) where they use them.

File formats (written by their ground stations, read here without a library because neither ground station
ships a Python reader; pymavlink's ``mavparm`` reads whitespace-separated files only and writes no header):

* QGroundControl ``.params`` (Parameters > Tools > Save to file): ``#`` comment lines, then one tab-separated
  row per parameter ``vehicle-id component-id name value type``; ``type`` is the MAVLink ``MAV_PARAM_TYPE``
  (6 = INT32, 9 = REAL32).
* Mission Planner ``.parm`` (Config > Full Parameter List > Save): ``#`` comment lines, then ``NAME,VALUE`` rows;
  ArduPilot's own ``.param`` files separate by white space, which is read too.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from rotorlab import atomic
from rotorlab.errors import ConfigError, DataError

__all__ = ["ParamSpec", "ParamTable", "read_qgc_params", "read_mp_parm", "read_params", "write_qgc_params",
           "write_mp_parm"]

_NAME = re.compile(r"^[A-Z][A-Z0-9_]{0,15}$")  # MAVLink parameter ids are at most 16 characters


@dataclass(frozen=True)
class ParamSpec:
    """One documented parameter.

    Attributes
    ----------
    name : str
        The autopilot's name (``MC_ROLLRATE_P``, ``ATC_RAT_RLL_P``).
    unit : str
        Unit as the autopilot documents it (``"1"`` for a dimensionless gain, ``"Hz"``, ``"deg/s"``,
        ``"norm/(rad/s)"`` for a gain from rate error to normalised torque).
    min, max : float or None
        Documented range; ``None`` where the autopilot documents no bound on that side.
    default : float
        The autopilot's default.
    description : str
        What the parameter does in the law.
    source : str
        File (and version) the range and default come from.
    integer : bool
        Stored as an integer parameter (MAVLink INT32).
    """

    name: str
    unit: str
    min: float | None
    max: float | None
    default: float
    description: str
    source: str
    integer: bool = False

    def in_range(self, value: float) -> bool:
        return (math.isfinite(value) and (self.min is None or value >= self.min)
                and (self.max is None or value <= self.max))

    def range_text(self) -> str:
        lo = "-inf" if self.min is None else f"{self.min:g}"
        hi = "inf" if self.max is None else f"{self.max:g}"
        return f"{lo} <= {self.name} <= {hi} {self.unit} ({self.source})"


class ParamTable:
    """The parameter table of one autopilot: ``table[name] -> ParamSpec``, in one place.

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> px4.TABLE["MC_ROLLRATE_P"].default
    0.15
    """

    def __init__(self, autopilot: str, specs):
        self.autopilot = autopilot
        self.specs = {s.name: s for s in specs}
        if len(self.specs) != len(specs):
            raise ValueError(f"{autopilot}: duplicate parameter names in the table")

    def __getitem__(self, name: str) -> ParamSpec:
        return self.specs[name]

    def __contains__(self, name) -> bool:
        return name in self.specs

    def __iter__(self):
        return iter(self.specs.values())

    def __len__(self) -> int:
        return len(self.specs)

    def defaults(self) -> dict[str, float]:
        """Every parameter at its documented default."""
        return {s.name: s.default for s in self}

    def complete(self, params: Mapping[str, float], fill_defaults: bool = False, source=None) -> dict[str, float]:
        """The table's parameters taken from ``params`` (other names ignored).

        Missing names are filled with defaults when ``fill_defaults``, else refused: a controller rebuilt from
        a log must not silently run on a default the vehicle never flew.

        Raises
        ------
        rotorlab.errors.DataError
            Naming the missing parameters and ``source`` (the file or log they were read from).
        """
        out, missing = {}, []
        for s in self:
            if s.name in params:
                out[s.name] = float(params[s.name])
            elif fill_defaults:
                out[s.name] = s.default
            else:
                missing.append(s.name)
        if missing:
            where = f"{source}: " if source is not None else ""
            raise DataError(f"{where}{self.autopilot} parameters missing for the controller: {', '.join(missing)} "
                            "(pass fill_defaults=True to use the autopilot's defaults)")
        return out

    def check(self, params: Mapping[str, float], file=None) -> None:
        """Refuse unknown names and values outside the documented ranges.

        Raises
        ------
        rotorlab.errors.ConfigError
            Naming the file, the parameter, the documented range and the value.
        """
        for name, value in params.items():
            if name not in self.specs:
                raise ConfigError(f"not a {self.autopilot} parameter this table documents", file=file, field=name,
                                  expected=f"one of {', '.join(sorted(self.specs))}", got=name)
            spec = self.specs[name]
            if not spec.in_range(float(value)):
                raise ConfigError("value outside the documented range", file=file, field=name,
                                  expected=spec.range_text(), got=float(value))
            if spec.integer and float(value) != int(value):
                raise ConfigError("integer parameter", file=file, field=name, expected="a whole number",
                                  got=float(value))


def _number(text: str, path, lineno: int, name: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(f"line {lineno}: not a number", file=path, field=name, expected="a number",
                          got=text) from None
    if not math.isfinite(v):
        raise ConfigError(f"line {lineno}: not finite", file=path, field=name, expected="a finite number", got=text)
    return v


def _lines(path):
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ConfigError(f"cannot read the parameter file ({exc.strerror or exc})", file=p) from None
    except UnicodeDecodeError:
        raise ConfigError("not a text parameter file", file=p, expected="UTF-8 text") from None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield lineno, line


def _check_name(name: str, path, lineno: int) -> None:
    if not _NAME.match(name):
        raise ConfigError(f"line {lineno}: not a parameter name", file=path, field="name",
                          expected="upper-case letters, digits and '_', at most 16 characters", got=name)


def read_qgc_params(path) -> dict[str, float]:
    """Read a QGroundControl ``.params`` file into ``{name: value}`` (all rows, in file order).

    Raises
    ------
    rotorlab.errors.ConfigError
        A row without 5 tab/space-separated fields, a bad name or value, a name given twice for one component
        (a name another component also has keeps the value of the component listed first, the autopilot in
        QGroundControl's files).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "a.params"
    >>> _ = p.write_text("# x\\n1\\t1\\tMC_ROLLRATE_P\\t0.2\\t9\\n")
    >>> read_qgc_params(p)
    {'MC_ROLLRATE_P': 0.2}
    """
    out: dict[str, float] = {}
    component: dict[str, str] = {}
    for lineno, line in _lines(path):
        fields = line.split()
        if len(fields) != 5:
            raise ConfigError(f"line {lineno}: a QGroundControl parameter row", file=path, field="row",
                              expected="'vehicle-id component-id name value type'", got=line)
        name = fields[2]
        _check_name(name, path, lineno)
        value = _number(fields[3], path, lineno, name)
        if name in out:
            if component[name] == fields[1]:
                raise ConfigError(f"line {lineno}: given twice", file=path, field=name,
                                  expected="one row per name and component", got=name)
            continue  # another component's parameter of that name (a gimbal, a camera): the first component's counts
        out[name], component[name] = value, fields[1]
    return out


def read_mp_parm(path) -> dict[str, float]:
    """Read a Mission Planner ``.parm`` (``NAME,VALUE``) or ArduPilot ``.param`` (``NAME VALUE``) file.

    Raises
    ------
    rotorlab.errors.ConfigError
        A row that is not ``NAME,VALUE``, a bad name or value, a name given twice.
    """
    out: dict[str, float] = {}
    for lineno, line in _lines(path):
        fields = [f for f in re.split(r"[,\s]+", line) if f]
        if len(fields) != 2:
            raise ConfigError(f"line {lineno}: a Mission Planner parameter row", file=path, field="row",
                              expected="'NAME,VALUE'", got=line)
        name = fields[0]
        _check_name(name, path, lineno)
        if name in out:
            raise ConfigError(f"line {lineno}: given twice", file=path, field=name, expected="one row per name",
                              got=name)
        out[name] = _number(fields[1], path, lineno, name)
    return out


def read_params(path) -> dict[str, float]:
    """Read a parameter file by its suffix: ``.params`` (QGroundControl), ``.parm`` / ``.param`` (Mission Planner)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".params":
        return read_qgc_params(path)
    if suffix in (".parm", ".param"):
        return read_mp_parm(path)
    raise ConfigError("unknown parameter file type", file=path, expected="a .params, .parm or .param file",
                      got=suffix or "(no suffix)")


def _header(header: str) -> str:
    return "".join(f"# {ln}\n" if ln else "#\n" for ln in header.splitlines())


def _fmt(spec: ParamSpec, value: float) -> str:
    # repr round-trips a float exactly; integers are written as integers
    return str(int(value)) if spec.integer else repr(float(value))


def write_qgc_params(path, params: Mapping[str, float], table: ParamTable, header: str,
                     vehicle_id: int = 1, component_id: int = 1) -> Path:
    """Write ``params`` (only those given) as a QGroundControl ``.params`` file, atomically.

    Every name must be in ``table`` and every value in its documented range (checked before anything is written).
    ``header`` (what was tuned against which goals) goes into ``#`` comment lines.
    """
    table.check(params, file=path)
    rows = [_header(header), "#\n# Vehicle-Id Component-Id Name Value Type\n"]
    for name in params:
        spec = table[name]
        rows.append(f"{vehicle_id}\t{component_id}\t{name}\t{_fmt(spec, params[name])}\t{6 if spec.integer else 9}\n")
    return atomic.write_text(path, "".join(rows))


def write_mp_parm(path, params: Mapping[str, float], table: ParamTable, header: str) -> Path:
    """Write ``params`` (only those given) as a Mission Planner ``.parm`` file (``NAME,VALUE``), atomically.

    Checked against ``table`` as :func:`write_qgc_params` is.
    """
    table.check(params, file=path)
    rows = [_header(header)] + [f"{name},{_fmt(table[name], params[name])}\n" for name in params]
    return atomic.write_text(path, "".join(rows))
