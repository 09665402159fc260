"""Discrete state-space controllers in place of the attitude cascade, with an optional anti-windup compensator.

A controller is data, not code: matrices with their own sample time, the named flight-software signals it
reads and the commands it sets (:class:`ControllerSpec`, a JSON or TOML file, :func:`load_controller`). The
flight software runs it as a plug-in (:class:`StateSpaceController`) after the built-in loops, so its outputs
replace the cascade's commands on the axes it drives, before the final saturation and the mixer.
``rotorlab.sim`` never imports ``rotorlab.tune``: a design (H-inf loop shaping, the modified PID, the Riccati
anti-windup compensator) arrives as matrices (``rotorlab.designs`` builds the TUHH ones).

Controller (every ``dt_s``, a multiple of the flight-software period; the output is held between updates)::

    v[k]  = [signals[name] for name in inputs] + S_y y_d[k]       (y_d on the inputs named in ``measurements``)
    u[k]  = C x[k] + D v[k] - u_d[k]
    x[k+1] = A x[k] + B v[k]

Anti-windup compensator ``Theta`` (ref. 002 eq. 16, discrete, strictly proper), driven by the part of the
command the saturation cuts off, ``u~ = u - sat(u)``::

    [u_d; y_d][k] = C_aw x_aw[k]        x_aw[k+1] = A_aw x_aw[k] + B_aw u~[k]

File format (JSON, or TOML with the same keys; unknown keys are errors)::

    {"format": "rotorlab-controller/1", "name": "hinf-pitch", "dt_s": 0.004,
     "inputs": ["theta_ref", "theta", "q"], "outputs": ["u_lon"],
     "A": [[...]], "B": [[...]], "C": [[...]], "D": [[...]],
     "u_limit_pct": [40.0],                                  (optional; default the flight software's limits)
     "antiwindup": {"measurements": ["theta", "q"], "A": ..., "B": ..., "C": ...},   (optional)
     "description": "..."}                                   (optional)

Units are the flight software's (deg, deg/s, %).
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
from pathlib import Path

import numpy as np

from rotorlab import atomic
from rotorlab.config import read_json, read_toml
from rotorlab.errors import ConfigError

FORMAT = "rotorlab-controller/1"
COMMANDS = ("u_col", "u_lat", "u_lon", "u_yaw")
_KEYS = {"format", "name", "dt_s", "inputs", "outputs", "A", "B", "C", "D", "u_limit_pct", "antiwindup",
         "description"}
_AW_KEYS = {"measurements", "A", "B", "C", "D"}


@dataclasses.dataclass(frozen=True)
class AntiWindup:
    """Anti-windup compensator: input ``u~`` (one per controller output, %), outputs ``u_d`` (one per
    controller output, %) then ``y_d`` (one per name in ``measurements``, in that signal's unit)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    measurements: tuple


@dataclasses.dataclass(frozen=True)
class ControllerSpec:
    """A discrete controller on named flight-software signals (see the module docstring)."""

    name: str
    dt_s: float
    inputs: tuple
    outputs: tuple
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    u_limit_pct: tuple | None = None
    antiwindup: AntiWindup | None = None
    description: str = ""

    def __post_init__(self):
        _check(self, "<ControllerSpec>")

    @property
    def nstates(self) -> int:
        return self.A.shape[0]

    def to_dict(self) -> dict:
        out = {"format": FORMAT, "name": self.name, "dt_s": self.dt_s, "inputs": list(self.inputs),
               "outputs": list(self.outputs), **{k: getattr(self, k).tolist() for k in "ABCD"}}
        if self.u_limit_pct is not None:
            out["u_limit_pct"] = list(self.u_limit_pct)
        if self.antiwindup is not None:
            aw = self.antiwindup
            out["antiwindup"] = {"measurements": list(aw.measurements), "A": aw.A.tolist(), "B": aw.B.tolist(),
                                 "C": aw.C.tolist()}
        if self.description:
            out["description"] = self.description
        return out


def _mat(v, src, fld, shape=None) -> np.ndarray:
    try:
        a = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(file=src, field=fld, expected="a matrix (list of rows of numbers)", got=v) from None
    if a.size == 0:
        a = np.zeros(shape if shape is not None else (0, 0))
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise ConfigError(file=src, field=fld, expected="a finite matrix (list of rows of numbers)", got=v)
    if shape is not None and a.shape != tuple(shape):
        raise ConfigError(file=src, field=fld, expected=f"shape {tuple(shape)}", got=a.shape)
    return a


def _check(spec: ControllerSpec, src) -> None:
    n, p, m = spec.A.shape[0], len(spec.inputs), len(spec.outputs)
    if not (isinstance(spec.dt_s, float) and math.isfinite(spec.dt_s) and spec.dt_s > 0):
        raise ConfigError(file=src, field="dt_s", expected="a sample time > 0 s", got=spec.dt_s)
    if not p or not m or len(set(spec.outputs)) != m:
        raise ConfigError(file=src, field="inputs/outputs", expected="non-empty lists of signal names, outputs unique",
                          got=(list(spec.inputs), list(spec.outputs)))
    bad = [x for x in spec.outputs if x not in COMMANDS]
    if bad:
        # an output named like a measurement or a set-point would overwrite that signal in the tick and the log
        # (after the loops used it), never act on the vehicle
        raise ConfigError("a controller sets flight-software commands only", file=src, field="outputs",
                          expected=f"names among {list(COMMANDS)}", got=bad[0])
    for k, shape in (("A", (n, n)), ("B", (n, p)), ("C", (m, n)), ("D", (m, p))):
        if getattr(spec, k).shape != shape:
            raise ConfigError(file=src, field=k, expected=f"shape {shape} for {n} states, {p} inputs, {m} outputs",
                              got=getattr(spec, k).shape)
    if spec.u_limit_pct is not None and (len(spec.u_limit_pct) != m or min(spec.u_limit_pct) <= 0):
        raise ConfigError(file=src, field="u_limit_pct", expected=f"{m} limits > 0 (one per output)",
                          got=spec.u_limit_pct)
    aw = spec.antiwindup
    if aw is not None:
        na = aw.A.shape[0]
        bad = [x for x in aw.measurements if x not in spec.inputs]
        if bad:
            raise ConfigError(file=src, field="antiwindup.measurements",
                              expected=f"names among inputs {list(spec.inputs)}",
                              got=bad)
        for k, shape in (("A", (na, na)), ("B", (na, m)), ("C", (m + len(aw.measurements), na))):
            if getattr(aw, k).shape != shape:
                raise ConfigError(file=src, field=f"antiwindup.{k}",
                                  expected=f"shape {shape} (input u~ per output; outputs u_d then y_d)",
                                  got=getattr(aw, k).shape)


def parse_controller(data: dict, src="<controller>") -> ControllerSpec:
    """Build a :class:`ControllerSpec` from the dict of a controller file (strict: unknown keys are errors)."""
    if not isinstance(data, dict):
        raise ConfigError(file=src, expected="a table of controller fields", got=type(data).__name__)
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise ConfigError(file=src, field=unknown[0], expected=f"one of {sorted(_KEYS)}", got=unknown[0])
    if data.get("format", FORMAT) != FORMAT:
        raise ConfigError(file=src, field="format", expected=FORMAT, got=data.get("format"))
    for k in ("dt_s", "inputs", "outputs", "A", "B", "C", "D"):
        if k not in data:
            raise ConfigError("missing field", file=src, field=k, expected="see rotorlab.sim.control.statespace")
    for k in ("inputs", "outputs"):
        if not isinstance(data[k], list) or not all(isinstance(x, str) for x in data[k]):
            raise ConfigError(file=src, field=k, expected="a list of signal names", got=data[k])
    dt = data["dt_s"]
    if isinstance(dt, bool) or not isinstance(dt, (int, float)):
        raise ConfigError(file=src, field="dt_s", expected="a sample time > 0 s", got=dt)
    p, m = len(data["inputs"]), len(data["outputs"])
    A = _mat(data["A"], src, "A")
    n = A.shape[0]
    B = _mat(data["B"], src, "B", (n, p) if n == 0 else None)
    C = _mat(data["C"], src, "C", (m, n) if n == 0 else None)
    D = _mat(data["D"], src, "D")
    lim = data.get("u_limit_pct")
    if lim is not None:
        if not isinstance(lim, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in lim):
            raise ConfigError(file=src, field="u_limit_pct", expected=f"a list of {m} limits in %", got=lim)
        lim = tuple(float(x) for x in lim)
    aw = None
    if "antiwindup" in data:
        a = data["antiwindup"]
        if not isinstance(a, dict):
            raise ConfigError(file=src, field="antiwindup", expected="a table", got=a)
        unknown = sorted(set(a) - _AW_KEYS)
        if unknown:
            raise ConfigError(file=src, field=f"antiwindup.{unknown[0]}", expected=f"one of {sorted(_AW_KEYS)}",
                              got=unknown[0])
        meas = a.get("measurements")
        if not isinstance(meas, list) or not all(isinstance(x, str) for x in meas):
            raise ConfigError(file=src, field="antiwindup.measurements", expected="a list of input names", got=meas)
        Aa = _mat(a.get("A"), src, "antiwindup.A")
        if "D" in a and np.any(_mat(a["D"], src, "antiwindup.D")):
            raise ConfigError("u~ is known only after the command it corrects", file=src, field="antiwindup.D",
                              expected="zeros (a strictly proper compensator, as for a strictly proper plant)",
                              got=a["D"])
        aw = AntiWindup(Aa, _mat(a.get("B"), src, "antiwindup.B"), _mat(a.get("C"), src, "antiwindup.C"),
                        tuple(meas))
    fields = dict(name=str(data.get("name", Path(str(src)).stem)), dt_s=float(dt), inputs=tuple(data["inputs"]),
                  outputs=tuple(data["outputs"]), A=A, B=B, C=C, D=D, u_limit_pct=lim, antiwindup=aw,
                  description=str(data.get("description", "")))
    _check(types.SimpleNamespace(**fields), src)  # errors name the file; the dataclass checks again
    return ControllerSpec(**fields)


def load_controller(path) -> ControllerSpec:
    """Read a controller file (``.json`` or ``.toml``)."""
    path = Path(path)
    if path.suffix == ".toml":
        return parse_controller(read_toml(path, "controller"), path)
    if path.suffix != ".json":
        raise ConfigError(file=path, expected="a controller file ending in .json or .toml", got=path.suffix)
    return parse_controller(read_json(path, "controller"), path)


def save_controller(path, spec: ControllerSpec) -> Path:
    """Write ``spec`` as JSON, atomically."""
    return atomic.write_text(path, json.dumps(spec.to_dict(), indent=1) + "\n")


class StateSpaceController:
    """Flight-software plug-in that runs a :class:`ControllerSpec` (see the module docstring).

    Parameters
    ----------
    spec : ControllerSpec
    tick_dt_s : float
        Flight-software period, s; ``spec.dt_s`` must be a whole multiple of it.
    u_limit_pct : sequence of float, optional
        Saturation of each output as the flight software applies it (what the anti-windup compensator
        sees); ``spec.u_limit_pct`` wins when the file gives one.
    """

    def __init__(self, spec: ControllerSpec, tick_dt_s: float, u_limit_pct=None):
        ratio = spec.dt_s / tick_dt_s
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ConfigError(f"controller '{spec.name}' runs every {spec.dt_s} s", field="dt_s",
                              expected=f"a whole multiple of the vehicle's flight-software period {tick_dt_s} s",
                              got=spec.dt_s)
        self.spec = spec
        self.every = int(round(ratio))
        lim = spec.u_limit_pct if spec.u_limit_pct is not None else u_limit_pct
        self.u_limit = np.full(len(spec.outputs), np.inf) if lim is None else np.asarray(lim, dtype=float)
        self.inputs, self.outputs = spec.inputs, spec.outputs
        aw = spec.antiwindup
        self._meas_idx = np.array([spec.inputs.index(n) for n in aw.measurements], dtype=int) if aw else None
        self.reset()

    def reset(self) -> None:
        self.x = np.zeros(self.spec.nstates)
        self.x_aw = np.zeros(self.spec.antiwindup.A.shape[0]) if self.spec.antiwindup else None
        self._k = 0
        self._held = {}

    def step(self, t: float, signals: dict) -> dict:
        k = self._k
        self._k += 1
        if k % self.every:
            return self._held
        s = self.spec
        try:
            v = np.array([signals[n] for n in s.inputs], dtype=float)
        except KeyError as exc:
            raise ConfigError(f"controller '{s.name}' input not among the tick's signals", field=str(exc.args[0]),
                              expected=f"one of {sorted(signals)}") from None
        m = len(s.outputs)
        aw = s.antiwindup
        if aw is not None:
            out = aw.C @ self.x_aw
            v[self._meas_idx] += out[m:]
            u = s.C @ self.x + s.D @ v - out[:m]
        else:
            u = s.C @ self.x + s.D @ v
        self.x = s.A @ self.x + s.B @ v
        if aw is not None:
            u_tilde = u - np.clip(u, -self.u_limit, self.u_limit)
            self.x_aw = aw.A @ self.x_aw + aw.B @ u_tilde
        self._held = {name: float(val) for name, val in zip(s.outputs, u)}
        return self._held


def as_controller_spec(obj) -> ControllerSpec:
    """A ControllerSpec, or the path of a controller file."""
    if isinstance(obj, ControllerSpec):
        return obj
    if isinstance(obj, (str, Path)):
        return load_controller(obj)
    raise ConfigError(field="controller", expected="a ControllerSpec or the path of a .json/.toml controller file",
                      got=type(obj).__name__)


__all__ = ["FORMAT", "AntiWindup", "ControllerSpec", "parse_controller", "load_controller", "save_controller",
           "StateSpaceController", "as_controller_spec"]
