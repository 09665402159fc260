"""Tuning specifications in TOML, read so the published requirements read almost word for word::

    [cascade]
    dt = 0.02
    axis = "pitch"
    two_dof = false
    tune = ["outer.kp", "outer.kd", "outer.tf", "inner.kp", "inner.ki", "inner.kd", "inner.tf"]

    [[goal]]
    type = "crossover"
    loop = "theta"
    band_rad_s = [3.5, 14.0]

Goal types: ``crossover`` (loop, band_rad_s), ``tracking`` (from, to, response_time_s, max_error_pct,
peak_error), ``rejection`` / ``gain`` (from, to, weight), ``sensitivity`` (point, weight), ``effort``
(from, to, max_gain), ``margins`` (point, gm_db, pm_deg), ``poles`` (min_damping, min_decay). Each goal takes an
optional ``hard = true/false``. A weight is a maximum-gain profile: a number, or
``{kind = "highpass", order, gain_db, corner_rad_s}``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from rotorlab.config import read_toml
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.tune import cascade as cas
from rotorlab.tune import goals as G

__all__ = ["Spec", "load_spec", "parse_spec", "builtin_specs", "SPEC_DIR"]

SPEC_DIR = Path(__file__).parent / "specs"


@dataclasses.dataclass
class Spec:
    name: str
    dt: float
    axis: str
    two_dof: bool
    tune: list
    goals: list


def builtin_specs() -> dict:
    return {p.stem: p for p in sorted(SPEC_DIR.glob("*.toml"))}


def _get(src, tbl, key, field, kind, default=dataclasses.MISSING):
    if key not in tbl:
        if default is dataclasses.MISSING:
            raise ConfigError("missing field", file=src, field=field, expected=kind)
        return default
    v = tbl[key]
    ok = {"number": lambda x: isinstance(x, (int, float)) and not isinstance(x, bool),
          "string": lambda x: isinstance(x, str), "bool": lambda x: isinstance(x, bool),
          "list": lambda x: isinstance(x, list), "table": lambda x: isinstance(x, dict)}[kind](v)
    if not ok:
        raise ConfigError(file=src, field=field, expected=f"a {kind}", got=v)
    return float(v) if kind == "number" else v


def _weight(src, field, w):
    if isinstance(w, (int, float)) and not isinstance(w, bool):
        if w <= 0:
            raise ConfigError(file=src, field=field, expected="a positive maximum gain", got=w)
        return float(w)
    if not isinstance(w, dict):
        raise ConfigError(file=src, field=field, expected="a number or a {kind = \"highpass\", ...} table", got=w)
    kind = w.get("kind")
    if kind != "highpass":
        raise ConfigError(file=src, field=f"{field}.kind", expected="'highpass'", got=kind)
    order = _get(src, w, "order", f"{field}.order", "number", 1.0)
    if order < 1 or order != int(order):
        raise ConfigError(file=src, field=f"{field}.order", expected="a whole number >= 1", got=order)
    gain_db = _get(src, w, "gain_db", f"{field}.gain_db", "number")
    corner = _get(src, w, "corner_rad_s", f"{field}.corner_rad_s", "number")
    if corner <= 0:
        raise ConfigError(file=src, field=f"{field}.corner_rad_s", expected="a positive frequency", got=corner)
    return G.highpass_max_gain(int(order), gain_db, corner)


def _goal(src, i, g):
    f = f"goal[{i}]"
    if not isinstance(g, dict):
        raise ConfigError(file=src, field=f, expected="a table", got=g)
    typ = _get(src, g, "type", f"{f}.type", "string")
    hard = g.get("hard")
    kw = {} if hard is None else {"hard": bool(hard)}
    try:
        if typ == "crossover":
            band = _get(src, g, "band_rad_s", f"{f}.band_rad_s", "list")
            if len(band) != 2:
                raise ConfigError(file=src, field=f"{f}.band_rad_s", expected="[wc_min, wc_max]", got=band)
            return G.CrossoverBand(_get(src, g, "loop", f"{f}.loop", "string"), float(band[0]), float(band[1]), **kw)
        if typ == "tracking":
            return G.Tracking(_get(src, g, "from", f"{f}.from", "string", "theta_ref"),
                              _get(src, g, "to", f"{f}.to", "string", "theta"),
                              _get(src, g, "response_time_s", f"{f}.response_time_s", "number"),
                              _get(src, g, "max_error_pct", f"{f}.max_error_pct", "number", 0.001) / 100.0,
                              _get(src, g, "peak_error", f"{f}.peak_error", "number", 1.0), **kw)
        if typ in ("rejection", "gain"):
            band = _get(src, g, "band_rad_s", f"{f}.band_rad_s", "list", [0.0, float("inf")])
            if len(band) != 2 or not all(isinstance(b, (int, float)) for b in band) or band[0] >= band[1]:
                raise ConfigError(file=src, field=f"{f}.band_rad_s", expected="[low, high] in rad/s", got=band)
            return G.Rejection(_get(src, g, "from", f"{f}.from", "string"), _get(src, g, "to", f"{f}.to", "string"),
                               _weight(src, f"{f}.weight", g.get("weight", 1.0)), band_rad_s=tuple(map(float, band)),
                               **kw)
        if typ == "sensitivity":
            return G.Sensitivity(_get(src, g, "point", f"{f}.point", "string"),
                                 _weight(src, f"{f}.weight", g.get("weight", 2.0)), **kw)
        if typ == "effort":
            return G.Effort(frm=_get(src, g, "from", f"{f}.from", "string", "theta_ref"),
                            to=_get(src, g, "to", f"{f}.to", "string", "u_ctrl"),
                            max_gain=_weight(src, f"{f}.max_gain", g.get("max_gain", 1.0)), **kw)
        if typ == "margins":
            return G.Margins(_get(src, g, "point", f"{f}.point", "string", "u"),
                             _get(src, g, "gm_db", f"{f}.gm_db", "number", 6.0),
                             _get(src, g, "pm_deg", f"{f}.pm_deg", "number", 45.0), **kw)
        if typ == "poles":
            return G.Poles(_get(src, g, "min_damping", f"{f}.min_damping", "number", 0.0),
                           _get(src, g, "min_decay", f"{f}.min_decay", "number", 0.0), **kw)
    except UnknownNameError as exc:
        raise ConfigError(str(exc), file=src, field=f) from None
    except ConfigError as exc:
        if exc.file is None:
            raise ConfigError(str(exc), file=src, field=f) from None
        raise
    raise ConfigError(file=src, field=f"{f}.type",
                      expected="one of crossover, tracking, rejection, gain, sensitivity, effort, margins, poles",
                      got=typ)


def parse_spec(data: dict, name: str = "spec", src="<spec>") -> Spec:
    if not isinstance(data, dict) or "cascade" not in data:
        raise ConfigError("missing [cascade] table", file=src, field="cascade")
    unknown = set(data) - {"cascade", "goal", "meta"}
    if unknown:
        raise ConfigError(file=src, field=sorted(unknown)[0], expected="[cascade], [[goal]] or [meta]",
                          got=sorted(unknown)[0])
    c = _get(src, data, "cascade", "cascade", "table")
    dt = _get(src, c, "dt", "cascade.dt", "number")
    if dt < 0:
        raise ConfigError(file=src, field="cascade.dt", expected="a sample time >= 0 s (0 = continuous)", got=dt)
    axis = _get(src, c, "axis", "cascade.axis", "string", "pitch")
    two_dof = _get(src, c, "two_dof", "cascade.two_dof", "bool", False)
    tune = _get(src, c, "tune", "cascade.tune", "list")
    for t in tune:
        if t not in cas.PARAM_NAMES or t == "outer.ki":
            raise ConfigError(file=src, field="cascade.tune", expected=f"names among {list(cas.PARAM_NAMES)}", got=t)
        if not two_dof and t.split(".")[1] in ("b", "c"):
            raise ConfigError("set-point weights are tuned only with two_dof = true", file=src, field="cascade.tune",
                              got=t)
    goals = data.get("goal", [])
    if not isinstance(goals, list) or not goals:
        raise ConfigError("a spec needs at least one [[goal]]", file=src, field="goal")
    return Spec(name=name, dt=dt, axis=axis, two_dof=two_dof, tune=list(tune),
                goals=[_goal(src, i, g) for i, g in enumerate(goals)])


def load_spec(path_or_name) -> Spec:
    """Read a spec file, or a built-in spec by name (``anteos-p2a2``, ``anteos-a2minib``)."""
    p = Path(path_or_name)
    if not p.exists():
        specs = builtin_specs()
        if str(path_or_name) in specs:
            p = specs[str(path_or_name)]
        elif p.suffix == ".toml":
            raise ConfigError("spec file not found", file=p)
        else:
            raise UnknownNameError("spec", str(path_or_name), specs)
    return parse_spec(read_toml(p, "spec"), name=p.stem, src=p)
