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

A spec for an autopilot's own loops (:class:`AutopilotSpec`, :mod:`rotorlab.tune.autopilot`) has an
``[autopilot]`` table (``name`` px4/ardupilot, ``dt`` the loop period in s, ``axes``) instead of ``[cascade]``, and
every ``[[goal]]`` names its ``axis``; :func:`rotorlab.tune.autopilot_spec.generic_spec` writes one from a plant.

Goal types (the registry :data:`rotorlab.tune.goals.GOAL_TYPES` that :meth:`~rotorlab.tune.goals.Goal.from_toml`
dispatches on): ``crossover`` (loop, band_rad_s), ``tracking`` (from, to, response_time_s, max_error_pct,
peak_error), ``rejection`` / ``gain`` (from, to, weight), ``sensitivity`` (point, weight), ``effort``
(from, to, max_gain), ``margins`` (point, gm_db, pm_deg), ``poles`` (min_damping, min_decay). Each goal takes an
optional ``hard = true/false``. A weight is a maximum-gain profile: a number, or
``{kind = "highpass", order, gain_db, corner_rad_s}``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from rotorlab.config import Table, read_toml
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.tune import cascade as cas
from rotorlab.tune import goals as G

__all__ = ["Spec", "AutopilotSpec", "load_spec", "parse_spec", "builtin_specs", "SPEC_DIR"]

SPEC_DIR = Path(__file__).parent / "specs"


@dataclasses.dataclass
class Spec:
    name: str
    dt: float
    axis: str
    two_dof: bool
    tune: list
    goals: list


#: shortest controller cycle of a spec, s: flight software runs at kHz rates at most (a 1e-300 s cycle reached
#: numpy as "Maximum allowed dimension exceeded")
MIN_DT_S = 1e-4


@dataclasses.dataclass
class AutopilotSpec:
    """A spec for an autopilot's own loops (:mod:`rotorlab.tune.autopilot`): ``[autopilot]`` with ``name``
    (px4, ardupilot), ``dt`` (loop period, s) and ``axes``; every ``[[goal]]`` names its ``axis``. Written by
    :func:`rotorlab.tune.autopilot_spec.generic_spec`."""

    name: str
    autopilot: str
    dt: float
    axes: list
    goals: dict  # axis -> [Goal]


def builtin_specs() -> dict:
    return {p.stem: p for p in sorted(SPEC_DIR.glob("*.toml"))}


def _parse_goal(src, g, i, axes=None):
    t = Table(src, g, f"goal[{i}].")
    axis = t.str("axis", choices=tuple(axes)) if axes is not None else None
    try:
        goal = G.Goal.from_toml(t)
    except UnknownNameError as exc:
        raise ConfigError(str(exc), file=src, field=f"goal[{i}]") from None
    except ConfigError as exc:
        if exc.file is None:  # raised by the goal itself: name where it came from
            raise ConfigError(str(exc), file=src, field=f"goal[{i}]") from None
        raise
    t.check_unknown()
    return axis, goal


def _parse_autopilot(top: Table, name, src) -> AutopilotSpec:
    from rotorlab.autopilots import AUTOPILOTS

    a = top.table("autopilot")
    ap = a.str("name", choices=tuple(AUTOPILOTS))
    dt = a.num("dt", lo=MIN_DT_S, hi=1.0)
    axes = a.strlist("axes", ["roll", "pitch", "yaw"], choices=("roll", "pitch", "yaw"))
    goals = top.raw("goal", [])
    if not isinstance(goals, list) or not goals:
        raise top.error("goal", "a spec needs at least one [[goal]]", expected="[[goal]] tables", got=goals)
    per_axis = {ax: [] for ax in axes}
    for i, g in enumerate(goals):
        axis, goal = _parse_goal(src, g, i, axes)
        per_axis[axis].append(goal)
    top.check_unknown()
    return AutopilotSpec(name=name, autopilot=ap, dt=dt, axes=list(axes), goals=per_axis)


def parse_spec(data: dict, name: str = "spec", src="<spec>") -> Spec | AutopilotSpec:
    """Read a spec from its TOML document, strictly: every key checked, every goal built from its type.

    Parameters
    ----------
    data : dict
        The TOML document as read by ``tomllib``: a ``[cascade]`` table (the published cascade's spec,
        :class:`Spec`) or an ``[autopilot]`` table (an autopilot's own loops, :class:`AutopilotSpec`), and
        ``[[goal]]`` entries.
    name : str
        The spec's name in reports.
    src : str or Path
        Where ``data`` came from, named in error messages.

    Returns
    -------
    Spec or AutopilotSpec

    Examples
    --------
    >>> from rotorlab import tune
    >>> spec = tune.parse_spec({"cascade": {"dt": 0.02, "tune": ["inner.kp", "inner.ki"]},
    ...                         "goal": [{"type": "margins", "point": "u", "gm_db": 6.0, "pm_deg": 40.0}]})
    >>> spec.tune, type(spec.goals[0]).__name__
    (['inner.kp', 'inner.ki'], 'Margins')
    """
    top = Table(src, data)
    top.table("meta", required=False, free=True)
    if "autopilot" in data:
        return _parse_autopilot(top, name, src)
    c = top.table("cascade")
    dt = c.num("dt", lo=0.0, hi=10.0)
    if 0 < dt < MIN_DT_S:
        raise c.error("dt", "the controller cycle time", expected=f"0 (continuous design) or at least {MIN_DT_S:g} s",
                      got=dt)
    axis = c.str("axis", "pitch", choices=("pitch", "roll"))
    two_dof = c.bool("two_dof", False)
    tune = c.strlist("tune", choices=cas.PARAM_NAMES)
    if not tune:  # nothing to tune reached the optimiser as a numpy reshape error
        raise c.error("tune", "nothing to tune", expected=f"at least one parameter of {list(cas.PARAM_NAMES)}",
                      got=tune)
    for t in tune:
        if not two_dof and t.split(".")[1] in ("b", "c"):
            raise c.error("tune", "set-point weights are tuned only with two_dof = true", got=t)
    goals = top.raw("goal", [])
    if not isinstance(goals, list) or not goals:
        raise top.error("goal", "a spec needs at least one [[goal]]", expected="[[goal]] tables", got=goals)
    parsed = [_parse_goal(src, g, i)[1] for i, g in enumerate(goals)]
    top.check_unknown()
    return Spec(name=name, dt=dt, axis=axis, two_dof=two_dof, tune=list(tune), goals=parsed)


def load_spec(path_or_name) -> Spec:
    """Read a spec file, or a built-in spec by name (``anteos-p2a2``, ``anteos-a2minib``).

    Parameters
    ----------
    path_or_name : str or Path
        A spec TOML file, or the name of a shipped spec (``tune/specs/NAME.toml``).

    Returns
    -------
    Spec
        The cascade settings and the goals.

    Raises
    ------
    ConfigError
        Naming the file and the field: an unknown key, a wrong type, an unknown goal type, a missing value.

    Examples
    --------
    >>> from rotorlab import tune
    >>> spec = tune.load_spec("anteos-p2a2")
    >>> spec.dt, spec.axis, len(spec.goals)
    (0.02, 'pitch', 8)
    """
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
