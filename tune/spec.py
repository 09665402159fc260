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
optional ``hard = true/false`` and an optional ``name``, the label reports give it (default: built from its type
and signals). A weight is a maximum-gain profile: a number, or
``{kind = "highpass", order, gain_db, corner_rad_s}``.

Units: ``[cascade] input_unit`` and ``output_unit`` state the plant units the spec (and the cascade's gains)
are written in: ``"%"`` and ``"deg/s"``, the flight software's (:data:`rotorlab.tune.cascade.PLANT_UNITS`; the
only values accepted, and the default). :func:`unit_conversion` checks a model's units against them.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import control as ct

from rotorlab.config import Table, read_toml
from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.tune import cascade as cas
from rotorlab.tune import goals as G

__all__ = ["Spec", "AutopilotSpec", "load_spec", "parse_spec", "builtin_specs", "SPEC_DIR", "unit_conversion",
           "model_in_spec_units"]

SPEC_DIR = Path(__file__).parent / "specs"


@dataclasses.dataclass
class Spec:
    name: str
    dt: float
    axis: str
    two_dof: bool
    tune: list
    goals: list
    input_unit: str = cas.PLANT_UNITS[0]
    output_unit: str = cas.PLANT_UNITS[1]


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
    # the cascade's gains are written in the flight software's units, so a spec can only state those
    input_unit = c.str("input_unit", cas.PLANT_UNITS[0], choices=(cas.PLANT_UNITS[0],))
    output_unit = c.str("output_unit", cas.PLANT_UNITS[1], choices=(cas.PLANT_UNITS[1],))
    for t in tune:
        if not two_dof and t.split(".")[1] in ("b", "c"):
            raise c.error("tune", "set-point weights are tuned only with two_dof = true", got=t)
    goals = top.raw("goal", [])
    if not isinstance(goals, list) or not goals:
        raise top.error("goal", "a spec needs at least one [[goal]]", expected="[[goal]] tables", got=goals)
    parsed = [_parse_goal(src, g, i)[1] for i, g in enumerate(goals)]
    top.check_unknown()
    return Spec(name=name, dt=dt, axis=axis, two_dof=two_dof, tune=list(tune), goals=parsed,
                input_unit=input_unit, output_unit=output_unit)


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


def unit_conversion(model_units: tuple, spec: Spec, file="model", convert: bool = False) -> tuple[float, float, str]:
    """Factors that put a model in the spec's units: ``(k_in, k_out, note)`` with ``G_spec = k_out G k_in``.

    ``k_in`` turns a command in the spec's input unit into the model's (``u_model = k_in u_spec``), ``k_out`` an
    output in the model's unit into the spec's (``y_spec = k_out y_model``). A unit the model lacks (None: an
    old file, a log without units) is taken as the spec's, and ``note`` says so. Matching units give ``(1, 1,
    "")``.

    Parameters
    ----------
    model_units : (str or None, str or None)
        The model's input and output units (:func:`rotorlab.ident.modelio.model_io_units`).
    spec : Spec
    file : str
        The model file, for messages.
    convert : bool
        Convert units that differ (``rotorlab tune --convert-units``); otherwise they are refused.

    Raises
    ------
    ConfigError
        Units that differ (without ``convert``; the message gives the factors to use), or that no factor
        converts (another quantity, a unit outside :data:`rotorlab.units.UNITS`).

    Examples
    --------
    >>> from rotorlab.tune.spec import load_spec, unit_conversion
    >>> k_in, k_out, note = unit_conversion(("1", "rad/s"), load_spec("anteos-p2a2"), convert=True)
    >>> k_in, round(k_out, 4)
    (0.01, 57.2958)
    """
    from rotorlab.units import factor

    u_unit, y_unit = model_units
    wanted = {"input": spec.input_unit, "output": spec.output_unit}
    got = {"input": u_unit, "output": y_unit}
    missing = [k for k, v in got.items() if v is None]
    k = {}
    differ = []
    for side in ("input", "output"):
        if got[side] is None or got[side] == wanted[side]:
            k[side] = 1.0
            continue
        # input: u_model = factor(spec -> model) u_spec; output: y_spec = factor(model -> spec) y_model
        f = factor(wanted[side], got[side]) if side == "input" else factor(got[side], wanted[side])
        if f is None:
            raise ConfigError(f"model {side} in {got[side]!r} cannot be converted to the spec's {wanted[side]!r} "
                              "(another quantity, or a unit rotorlab does not convert: docs/units.md)",
                              file=file, field="units", expected=f"{side} in {wanted[side]!r}", got=got[side])
        k[side] = f
        if f != 1.0:
            differ.append(f"model {side} {got[side]}, spec {wanted[side]}: scale the {side} by {f:.6g}")
    if differ and not convert:
        raise ConfigError("; ".join(differ) + f" (G in the spec's units = {k['output'] * k['input']:.6g} G); pass "
                          "--convert-units to tune on the converted model, or identify from a log in the spec's "
                          "units", file=file, field="units",
                          expected=f"input {wanted['input']!r} and output {wanted['output']!r} (the spec's)",
                          got=f"input {u_unit!r} and output {y_unit!r}")
    notes = []
    if differ:
        notes.append("converted to the spec's units: " + "; ".join(differ))
    if missing:
        notes.append(f"carries no unit for its {' and '.join(missing)}: taken as the spec's "
                     + " and ".join(f"{wanted[m]}" for m in missing) + " (docs/units.md)")
    return k["input"], k["output"], "; ".join(notes)


def model_in_spec_units(sys, model_units: tuple, spec: Spec, file="model", convert: bool = False):
    """``(G_spec, note)``: the model ``sys`` (LTI, SISO) in the spec's units, ``k_out G k_in`` with the factors
    of :func:`unit_conversion` (which raises for units that differ without ``convert``), as a state space."""
    from rotorlab import lti

    k_in, k_out, note = unit_conversion(model_units, spec, file, convert)
    G = lti.as_ss(sys)
    if (k_in, k_out) == (1.0, 1.0):
        return G, note
    return ct.ss(G.A, G.B * k_in, G.C * k_out, G.D * (k_in * k_out), G.dt), note
