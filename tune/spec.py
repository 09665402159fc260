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
import difflib
import math
from pathlib import Path

from rotorlab.config import REQUIRED, Table, _is_number, read_toml
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


def _weight(g: Table, key, default):
    """A maximum-gain profile: a positive number or a ``{kind = "highpass", order, gain_db, corner_rad_s}`` table."""
    w = g.raw(key, default)
    if _is_number(w):
        return g.num(key, default, lo=0.0, lo_open=True)
    if not isinstance(w, dict):
        raise g.error(key, expected='a positive number or a {kind = "highpass", ...} table', got=w)
    t = g.table(key)
    t.str("kind", choices=("highpass",))
    order = t.int("order", 1, lo=1, hi=8)
    gain_db = t.num("gain_db", lo=-200.0, hi=200.0)
    corner = t.num("corner_rad_s", lo=0.0, lo_open=True)
    return G.highpass_max_gain(order, gain_db, corner)


def _band(g: Table, key, default=REQUIRED):
    band = g.vec(key, 2, default, lo=0.0, allow_inf=True)
    if band[0] >= band[1] or math.isinf(band[0]):
        raise g.error(key, expected="[low, high] in rad/s with low < high", got=list(band))
    return band


def _goal(g: Table):
    """One [[goal]]: the keys each goal type reads are the only ones it accepts."""
    typ = g.str("type", choices=GOAL_TYPES)
    kw = {"hard": g.bool("hard")} if "hard" in g else {}
    if typ == "crossover":
        lo, hi = _band(g, "band_rad_s")
        return G.CrossoverBand(g.str("loop"), lo, hi, **kw)
    if typ == "tracking":
        return G.Tracking(g.str("from", "theta_ref"), g.str("to", "theta"),
                          g.num("response_time_s", lo=0.0, lo_open=True),
                          g.num("max_error_pct", 0.001, lo=0.0, lo_open=True, hi=100.0) / 100.0,
                          g.num("peak_error", 1.0, lo=0.0, lo_open=True), **kw)
    if typ in ("rejection", "gain"):
        return G.Rejection(g.str("from"), g.str("to"), _weight(g, "weight", 1.0),
                           band_rad_s=_band(g, "band_rad_s", (0.0, math.inf)), **kw)
    if typ == "sensitivity":
        return G.Sensitivity(g.str("point"), _weight(g, "weight", 2.0), **kw)
    if typ == "effort":
        return G.Effort(frm=g.str("from", "theta_ref"), to=g.str("to", "u_ctrl"),
                        max_gain=_weight(g, "max_gain", 1.0), **kw)
    if typ == "margins":
        return G.Margins(g.str("point", "u"), g.num("gm_db", 6.0, lo=0.0, hi=100.0),
                         g.num("pm_deg", 45.0, lo=0.0, hi=180.0), **kw)
    return G.Poles(g.num("min_damping", 0.0, lo=0.0, hi=1.0), g.num("min_decay", 0.0, lo=0.0), **kw)


GOAL_TYPES = ("crossover", "tracking", "rejection", "gain", "sensitivity", "effort", "margins", "poles")


def parse_spec(data: dict, name: str = "spec", src="<spec>") -> Spec:
    top = Table(src, data)
    top.table("meta", required=False, free=True)
    c = top.table("cascade")
    dt = c.num("dt", lo=0.0, hi=10.0)
    axis = c.str("axis", "pitch", choices=("pitch", "roll"))
    two_dof = c.bool("two_dof", False)
    tune = c.strlist("tune")
    for t in tune:
        if t not in cas.PARAM_NAMES or t == "outer.ki":
            close = difflib.get_close_matches(t, list(cas.PARAM_NAMES), n=1)
            raise c.error("tune", expected=f"names among {[p for p in cas.PARAM_NAMES if p != 'outer.ki']}", got=t,
                          hint=f"did you mean '{close[0]}'?" if close else None)
        if not two_dof and t.split(".")[1] in ("b", "c"):
            raise c.error("tune", "set-point weights are tuned only with two_dof = true", got=t)
    goals = top.raw("goal", [])
    if not isinstance(goals, list) or not goals:
        raise top.error("goal", "a spec needs at least one [[goal]]", expected="[[goal]] tables", got=goals)
    parsed = []
    for i, g in enumerate(goals):
        t = Table(src, g, f"goal[{i}].")
        try:
            parsed.append(_goal(t))
        except UnknownNameError as exc:
            raise ConfigError(str(exc), file=src, field=f"goal[{i}]") from None
        except ConfigError as exc:
            if exc.file is None:  # raised by the goal itself: name where it came from
                raise ConfigError(str(exc), file=src, field=f"goal[{i}]") from None
            raise
        t.check_unknown()
    top.check_unknown()
    return Spec(name=name, dt=dt, axis=axis, two_dof=two_dof, tune=list(tune), goals=parsed)


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
