"""Calibrate a multirotor twin to per-axis rate models (identified from a flight log, or any LTI model).

The target of each axis is a model from axis command (%, the flight software's units) to body rate (deg/s,
aerospace signs), continuous or discrete, with an optional transport delay. The twin's model is its own true
linearisation (``rotorlab.sim.linearize``), so everything the twin has (IMU mount, rotor drag, rotor-inertia yaw
reaction) stays in. Its scene is the ``gimbal`` by default: the hovering twin on a frictionless ball joint at its
CG, free to rotate and held in place, which is what a per-axis rotational model (rigid body, motor, delay, as
rotorlab ident's structures) describes; in ``free-flight`` the translation also feeds back (the rotors' in-plane
drag above the CG: a pendulum-like mode that moves the TUHH twin's roll response by 10.5 dB and 83 deg at 1 rad/s
against 0.5 deg and 0.01 dB on the gimbal), for targets that include it. What is fitted are the physical
parameters a rate response determines:

* the principal moments of inertia (one per fitted axis),
* the motor time constant ``lag_s`` (one per rotor group, see below),
* the transport delay ``delay_s`` (one per rotor group),
* with a yaw target on a variable-RPM twin, the two rotor numbers yaw needs besides its inertia: the rotor inertia
  ``J_R`` (the spin-up reaction ``J_R dOmega/dt``, a zero at ``q / J_R``) and the rotors' in-plane drag
  ``hforce_N_per_mps`` (yaw damping ``n k_h arm^2``, a pole below the band whose phase reaches into it: 22 deg at
  1 rad/s on the TUHH twin). ``vehicle new`` estimates neither, and a yaw response without them would drag the
  motor poles the axes share to their bounds.

Rotor groups: in the plus layout roll is driven by rotors 2/4 and pitch by rotors 1/3 only, so each pair gets
its own motor pole and delay (ref. 002 identifies them per axis); in the X and hexa layouts every rotor drives both
axes, so one pole and one delay are shared. The torque gain is held at the thrust-stand value: a rate response
fixes only the ratio torque gain / inertia per axis (``b`` of ``b / s``), so fitting both would be unidentifiable;
a gain error therefore shows up as an inertia error of the same ratio (the rate response is still right).

The fit is a bounded least-squares on the log of the frequency-response ratio (real part: gain, imaginary: phase)
over :data:`W_FIT_RAD_S`, 1-30 rad/s (scipy.optimize.least_squares); the bounds keep the parameters physical
(:data:`INERTIA_FACTOR_RANGE` of the start, :data:`LAG_RANGE_S`, :data:`DELAY_RANGE_S`), and the inertia the
triangle inequality (checked when the result is loaded). During the fit the delay is a continuous factor
``exp(-j w T_d)`` on the delay-free linearisation; the result rounds it to whole physics steps (MuJoCo realises
it with its actuator history) and the reported residual is the rounded twin's exact linearisation.

Examples
--------
>>> import control as ct
>>> from rotorlab.vehicles import load_vehicle
>>> from rotorlab.vehicles.fit_axes import calibrate_axes
>>> v = load_vehicle("x500")
>>> target = ct.tf([93.3], [0.02, 1.0, 0.0])  # deg/s per %: b / (s (tau s + 1))
>>> result = calibrate_axes(v, {"roll": target, "pitch": target})  # doctest: +SKIP
>>> result.max_error_db, result.max_error_deg  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import mujoco
import numpy as np
import scipy.optimize as so

from rotorlab import atomic, lti
from rotorlab.errors import ConfigError
from rotorlab.scenes import PHYSICS_DT_S, build_scene
from rotorlab.sim.linearize import linearize

from .spec import VehicleSpec, load_vehicle_file

AXES = ("roll", "pitch", "yaw")
INERTIA_INDEX = {"roll": 0, "pitch": 1, "yaw": 2}
W_FIT_RAD_S = np.logspace(0.0, math.log10(30.0), 25)
INERTIA_FACTOR_RANGE = (1.0 / 3.0, 3.0)  # of the starting value: a geometry estimate is good to a factor of 3
LAG_RANGE_S = (0.002, 0.2)  # motor time constants of flying multirotors
DELAY_RANGE_S = (0.0, 0.1)  # flight-stack delays; more is no flyable aircraft
ROTOR_INERTIA_RANGE_KGM2 = (1e-7, 1e-3)  # propeller + bell, 3-inch to 30-inch propellers
HFORCE_RANGE_N_PER_MPS = (1e-4, 1.0)  # rotor in-plane drag per m/s
ROTOR_START = {"inertia_kgm2": 1e-5, "hforce_N_per_mps": 0.01}  # where the fit starts when the file says 0
TRIANGLE_PENALTY = 100.0  # residual per relative excess over the triangle inequality (a 1 % excess: 1 neper)


def rotor_groups(v: VehicleSpec) -> dict:
    """Rotor groups (0-based rotor indices) that share one motor pole and delay, and the axis each group
    drives alone (None: shared by every axis)."""
    if v.frame == "quad-plus":
        return {"pitch": (0, 2), "roll": (1, 3)}
    return {None: tuple(range(v.n_rotors))}


def _axis_groups(groups: dict, axis: str) -> list:
    """The groups that drive ``axis``: its own group in the plus layout, else every group."""
    return [axis] if axis in groups else list(groups)


def axis_delay_s(v: VehicleSpec, axis: str) -> float:
    """The transport delay of ``axis``'s command, s: the mean over the rotors that drive it (in the plus layout
    roll's pair or pitch's pair alone, yaw every rotor; otherwise every rotor), the delay :func:`calibrate_axes`
    fits for that axis. Yaw on a plus frame mixes two pairs: two paths ``d +- e`` differ from one at their mean
    by the factor ``cos(w e)`` in gain and nothing in phase (tuhh-quad, 24 and 28 ms: 0.005 dB at 30 rad/s).

    Examples
    --------
    >>> from rotorlab.vehicles import load_vehicle
    >>> v = load_vehicle("tuhh-quad")
    >>> [round(axis_delay_s(v, a), 3) for a in ("roll", "pitch", "yaw")]
    [0.024, 0.028, 0.026]
    """
    groups = rotor_groups(v)
    rotors = [k for g in _axis_groups(groups, axis) for k in groups[g]]
    return float(np.mean([v.rotor.delay_s[k] for k in rotors]))


@dataclasses.dataclass(frozen=True)
class AxisResidual:
    """Frequency-by-frequency residual of one axis: twin / target, in dB and deg, at ``w_rad_s``."""

    axis: str
    w_rad_s: np.ndarray
    error_db: np.ndarray
    error_deg: np.ndarray

    @property
    def max_db(self) -> float:
        return float(np.max(np.abs(self.error_db)))

    @property
    def max_deg(self) -> float:
        return float(np.max(np.abs(self.error_deg)))


@dataclasses.dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate_axes`: the calibrated vehicle, its fitted values, and residuals before/after."""

    vehicle: VehicleSpec
    inertia_kgm2: tuple
    lag_s: tuple  # per rotor
    delay_s: tuple  # per rotor, whole physics steps
    rotor_inertia_kgm2: float | None  # fitted J_R (None: not fitted)
    hforce_N_per_mps: float | None  # fitted rotor in-plane drag (None: not fitted)
    residual: dict  # axis -> AxisResidual of the calibrated twin
    residual_start: dict  # axis -> AxisResidual of the starting twin
    cost_evaluations: int
    #: parameters that ended on a bound of their physical range: the model asks for more than the range allows
    #: there (or, for a delay at 0, the target has none)
    at_bounds: tuple = ()

    @property
    def max_error_db(self) -> float:
        return max(r.max_db for r in self.residual.values())

    @property
    def max_error_deg(self) -> float:
        return max(r.max_deg for r in self.residual.values())

    def table(self) -> str:
        """The residual over frequency, one row per frequency, columns dB and deg per axis (plain text)."""
        axes = list(self.residual)
        head = "w rad/s " + " ".join(f"{a + ' dB':>9} {a + ' deg':>9}" for a in axes)
        rows = [head]
        w = self.residual[axes[0]].w_rad_s
        for k, wk in enumerate(w):
            rows.append(f"{wk:7.2f} " + " ".join(f"{self.residual[a].error_db[k]:9.3f} {self.residual[a].error_deg[k]:9.3f}"
                                                 for a in axes))
        return "\n".join(rows)


def _target_response(target, w) -> np.ndarray:
    model, delay_s = target if isinstance(target, tuple) else (target, 0.0)
    return lti.freqresp(model, w)[:, 0, 0] * np.exp(-1j * w * float(delay_s))


def _triangle(inertia) -> tuple[tuple, float]:
    """``inertia`` with each moment capped at the sum of the other two (any rigid body's principal moments obey
    it, and MuJoCo refuses a body that does not), and the relative excess that was cut off."""
    i = [float(x) for x in inertia]
    excess = 0.0
    for c in range(3):
        s = sum(i) - i[c]
        if i[c] > s:
            excess += i[c] / s - 1.0
            i[c] = s * (1.0 - 1e-9)
    return tuple(i), excess


def _with(v: VehicleSpec, inertia, lag, delay, yaw_rotor=None) -> VehicleSpec:
    extra = {} if yaw_rotor is None else dict(zip(ROTOR_START, map(float, yaw_rotor), strict=True))
    rotor = dataclasses.replace(v.rotor, lag_s=tuple(float(x) for x in lag), delay_s=tuple(float(x) for x in delay),
                                **extra)
    return dataclasses.replace(v, inertia_kgm2=tuple(float(x) for x in inertia), rotor=rotor)


SCENES = ("gimbal", "free-flight")


def _gimbal(spec, scene: str, v) -> bool:
    # the free-flight scene's free joint becomes a ball joint at the airframe origin, which is the CG
    next(j for j in spec.joints if j.name == "free").type = mujoco.mjtJoint.mjJNT_BALL
    return False  # no rope anchor


def twin_scene(v: VehicleSpec, scene: str = "gimbal"):
    """The twin in ``scene``: ``gimbal`` (rotation about the CG only) or ``free-flight``."""
    if scene not in SCENES:
        raise ConfigError("the calibration scene", field="scene", expected=f"one of {SCENES}", got=scene)
    return build_scene("free-flight", v, edit=_gimbal if scene == "gimbal" else None)


def twin_response(v: VehicleSpec, axes, w, delay: bool = True, scene: str = "gimbal") -> dict:
    """The twin's rate response per axis (axis command % -> gyro deg/s) at ``w`` rad/s in ``scene``."""
    G = linearize(twin_scene(v, scene), v, list(axes), [f"gyro_{a}" for a in axes], delay=delay)
    H = lti.freqresp(G, w)
    return {a: H[:, i, i] for i, a in enumerate(axes)}


def _residual(axis, w, twin, target) -> AxisResidual:
    r = np.log(twin / target)
    return AxisResidual(axis, np.asarray(w), 20.0 / math.log(10.0) * r.real, np.degrees(r.imag))


def axis_residuals(v: VehicleSpec, targets: dict, w_rad_s=W_FIT_RAD_S, scene: str = "gimbal") -> dict:
    """The residual twin / target per axis of ``targets`` (as :func:`calibrate_axes` takes them) at ``w_rad_s``:
    axis -> :class:`AxisResidual`, of the twin's exact linearisation (delays in its physics steps).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab.vehicles import load_vehicle
    >>> r = axis_residuals(load_vehicle("x500"), {"roll": ct.tf([93.3], [0.02, 1.0, 0.0])})
    >>> r["roll"].max_db > 0.0
    True
    """
    w = np.asarray(w_rad_s, dtype=float)
    axes = [a for a in AXES if a in targets]
    twin = twin_response(v, axes, w, scene=scene)
    return {a: _residual(a, w, twin[a], _target_response(targets[a], w)) for a in axes}


def calibrate_axes(vehicle: VehicleSpec, targets: dict, w_rad_s=W_FIT_RAD_S, scene: str = "gimbal",
                   yaw_rotor: bool | None = None, fit_motors: bool = True) -> Calibration:
    """Fit the twin's inertia, motor poles and delays to per-axis rate models.

    Parameters
    ----------
    vehicle : VehicleSpec
        The starting twin (e.g. written by ``rotorlab vehicle new``): right mass, geometry and rotor.
    targets : dict
        ``{axis: model}`` or ``{axis: (model, delay_s)}`` for any of ``roll``, ``pitch``, ``yaw``: a
        python-control LTI model (continuous or discrete) from axis command (%) to rate (deg/s); an axis not given
        keeps its inertia.
    w_rad_s : array
        Fit frequencies, rad/s (default 25 points log-spaced over 1-30).
    scene : {'gimbal', 'free-flight'}
        Where the twin is linearised (see the module docstring).
    yaw_rotor : bool, optional
        Fit the rotor inertia and in-plane drag too (default: when yaw is a target of a variable-RPM twin).
    fit_motors : bool
        Fit the motor lags and delays (default); False keeps the vehicle's, e.g. a yaw fit after roll and pitch
        have set them (a yaw record alone does not separate lag from delay).

    Returns
    -------
    Calibration
        The calibrated vehicle (delays in whole physics steps) and its residual over frequency, dB and deg.
    """
    axes = [a for a in AXES if a in targets]
    if not axes or set(targets) - set(AXES):
        raise ConfigError("calibration targets", field="targets", expected=f"models for some of {AXES}",
                          got=sorted(targets))
    if _triangle(vehicle.inertia_kgm2)[1] > 0:
        raise ConfigError("principal moments of a rigid body obey I_a + I_b >= I_c", file=vehicle.path,
                          field="airframe.inertia_kgm2", expected="a physical starting inertia",
                          got=list(vehicle.inertia_kgm2))
    w = np.asarray(w_rad_s, dtype=float)
    goal = {a: _target_response(targets[a], w) for a in axes}
    groups = rotor_groups(vehicle)
    names = list(groups)
    n_i, n_g = len(axes), len(names)
    i0 = np.array([vehicle.inertia_kgm2[INERTIA_INDEX[a]] for a in axes])
    lag0 = np.array([np.mean([vehicle.rotor.lag_s[k] for k in groups[g]]) for g in names])
    del0 = np.array([np.mean([vehicle.rotor.delay_s[k] for k in groups[g]]) for g in names])
    if yaw_rotor is None:
        yaw_rotor = "yaw" in axes and vehicle.kind == "variable-rpm"
    n_r = 2 if yaw_rotor else 0
    r0 = np.array([getattr(vehicle.rotor, k) or ROTOR_START[k] for k in ROTOR_START][:n_r])
    n_s = n_i + n_g + n_r  # the parameters the delay-free linearisation depends on

    def unpack(x):
        inertia = list(vehicle.inertia_kgm2)
        for a, val in zip(axes, np.exp(x[:n_i]), strict=True):
            inertia[INERTIA_INDEX[a]] = val
        lag, delay = list(vehicle.rotor.lag_s), list(vehicle.rotor.delay_s)
        for g, lg, dg in zip(names, np.exp(x[n_i:n_i + n_g]), x[n_s:], strict=True):
            for k in groups[g] if fit_motors else ():  # held motors stay the vehicle's, bit for bit
                lag[k], delay[k] = lg, dg
        return inertia, lag, delay, (np.exp(x[n_i + n_g:n_s]) if yaw_rotor else None)

    cache = {}

    def undelayed(key):
        # the delay-free linearisation does not depend on the delays: their finite differences reuse it
        if key not in cache:
            inertia, lag, delay, rot = unpack(np.array(key + (0.0,) * n_g))
            # a trial point outside the triangle inequality is evaluated at its projection and pays the excess,
            # so the residual stays continuous and the fit walks back to physical inertias
            inertia, excess = _triangle(inertia)
            H = twin_response(_with(vehicle, inertia, lag, delay, rot), axes, w, delay=False, scene=scene)
            cache[key] = H, excess
        return cache[key]

    def resid(x):
        H, excess = undelayed(tuple(float(v) for v in x[:n_s]))
        out = [np.array([TRIANGLE_PENALTY * excess])]
        for a in axes:
            td = np.mean([x[n_s + names.index(g)] for g in _axis_groups(groups, a)])
            r = np.log(H[a] * np.exp(-1j * w * td) / goal[a])
            out += [r.real, r.imag]
        return np.concatenate(out)

    rot_lo = np.log([ROTOR_INERTIA_RANGE_KGM2[0], HFORCE_RANGE_N_PER_MPS[0]][:n_r])
    rot_hi = np.log([ROTOR_INERTIA_RANGE_KGM2[1], HFORCE_RANGE_N_PER_MPS[1]][:n_r])
    x0 = np.concatenate([np.log(i0), np.log(lag0), np.log(r0), del0])
    lo = np.concatenate([np.log(i0 * INERTIA_FACTOR_RANGE[0]), np.full(n_g, math.log(LAG_RANGE_S[0])), rot_lo,
                         np.full(n_g, DELAY_RANGE_S[0])])
    hi = np.concatenate([np.log(i0 * INERTIA_FACTOR_RANGE[1]), np.full(n_g, math.log(LAG_RANGE_S[1])), rot_hi,
                         np.full(n_g, DELAY_RANGE_S[1])])
    free = np.ones(x0.size, dtype=bool)
    if not fit_motors:
        free[n_i:n_i + n_g] = free[n_s:] = False
    # the fitted parameters start inside their bounds; held ones keep their values exactly
    x0 = np.where(free, np.clip(x0, lo + 1e-9, hi - 1e-9), x0)

    def full(xf):
        x = x0.copy()
        x[free] = xf
        return x

    # x_scale: a unit step is a factor e in every other parameter and 10 ms of delay, so the trust region moves
    # them alike; the tolerances let it walk the lag-delay valley to its end (xtol stops it early otherwise)
    x_scale = np.concatenate([np.ones(n_s), np.full(n_g, 0.01)])
    sol = so.least_squares(lambda xf: resid(full(xf)), x0[free], bounds=(lo[free], hi[free]), x_scale=x_scale[free],
                           diff_step=1e-3, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    sol.x = full(sol.x)
    labels = ([f"inertia {a}" for a in axes] + [f"motor lag {g or 'all rotors'}" for g in names]
              + ["rotor inertia", "rotor in-plane drag"][:n_r] + [f"delay {g or 'all rotors'}" for g in names])
    # within 0.1 % of a bound (log parameters) or half a physics step (delays, which are rounded to steps)
    tol = np.concatenate([np.full(n_s, 1e-3), np.full(n_g, 0.5 * PHYSICS_DT_S)])
    at_bounds = tuple(f"{name} at its {'lower' if x - a < b - x else 'upper'} bound"
                      for name, x, a, b, t, f in zip(labels, sol.x, lo, hi, tol, free, strict=True)
                      if f and min(x - a, b - x) < t)
    inertia, lag, delay, rot = unpack(sol.x)
    inertia = _triangle(inertia)[0]
    delay = [round(d / PHYSICS_DT_S) * PHYSICS_DT_S for d in delay]
    fitted = _with(vehicle, inertia, lag, delay, rot)
    return Calibration(
        vehicle=fitted, inertia_kgm2=tuple(fitted.inertia_kgm2), lag_s=tuple(fitted.rotor.lag_s),
        delay_s=tuple(fitted.rotor.delay_s),
        rotor_inertia_kgm2=fitted.rotor.inertia_kgm2 if yaw_rotor else None,
        hforce_N_per_mps=fitted.rotor.hforce_N_per_mps if yaw_rotor else None,
        residual=axis_residuals(fitted, targets, w, scene), residual_start=axis_residuals(vehicle, targets, w, scene),
        cost_evaluations=int(sol.nfev), at_bounds=at_bounds)


def calibrate_axes_staged(vehicle: VehicleSpec, targets: dict, **kw) -> Calibration:
    """:func:`calibrate_axes` in two stages where yaw is a target beside roll or pitch: the motors' lag and delay
    (with the roll and pitch inertias) from roll and pitch, then every axis with the motors held
    (``fit_motors=False``), which moves the inertias and yaw's rotor terms. Yaw's rate response separates the
    motor lag from the delay only weakly (its loop crosses over far below the motor pole, and PX4 low-passes its
    torque), so fitted jointly its target pulls the motors that roll and pitch determine; flight-log
    identification borrows them the same way (rotorlab.ident.flightlogs.plant_structures). Otherwise the same
    as :func:`calibrate_axes`; ``residual_start`` is the starting vehicle's.

    Examples
    --------
    >>> cal = calibrate_axes_staged(start, {"roll": G_r, "pitch": G_p, "yaw": G_y})  # doctest: +SKIP
    """
    tilt = {a: t for a, t in targets.items() if a != "yaw"}
    if not tilt or "yaw" not in targets:
        return calibrate_axes(vehicle, targets, **kw)
    first = calibrate_axes(vehicle, tilt, **kw)
    cal = calibrate_axes(first.vehicle, targets, fit_motors=False, **kw)
    start = axis_residuals(vehicle, targets, kw.get("w_rad_s", W_FIT_RAD_S), kw.get("scene", "gimbal"))
    return dataclasses.replace(cal, residual_start=start, cost_evaluations=first.cost_evaluations + cal.cost_evaluations,
                               at_bounds=tuple(dict.fromkeys(first.at_bounds + cal.at_bounds)))


def _set_key(lines: list, section: str, key: str, value: str, note: str) -> None:
    """Replace ``key = ...`` in ``[section]`` of TOML ``lines`` (one-line values), or add it after the header."""
    current, header_at = None, None
    for i, line in enumerate(lines):
        m = re.match(r"\s*\[([^\]]+)\]", line)
        if m:
            current = m.group(1).strip()
            if current == section:
                header_at = i
            continue
        if current == section and re.match(rf"\s*{re.escape(key)}\s*=", line):
            lines[i] = f"{key} = {value}  # {note}"
            return
    if header_at is None:
        raise ConfigError("the vehicle file has no such table", field=section, expected=f"[{section}]")
    lines.insert(header_at + 1, f"{key} = {value}  # {note}")


def write_calibrated(source, result: Calibration, out, note: str = "calibrated (rotorlab.vehicles.fit_axes)") -> Path:
    """Write ``source`` (a vehicle TOML) with the calibrated inertia, lags and delays to ``out`` (atomically),
    every other line and comment kept; the written file is read back (triangle inequality, delay steps)."""
    source, out = Path(source), Path(out)
    lines = source.read_text(encoding="utf-8").splitlines()

    def vec(xs):
        return "[" + ", ".join(repr(float(x)) for x in xs) + "]"

    _set_key(lines, "airframe", "inertia_kgm2", vec(result.inertia_kgm2), note)
    _set_key(lines, "rotor", "lag_s", vec(result.lag_s), note)
    _set_key(lines, "rotor", "delay_s", vec(result.delay_s), note)
    if result.rotor_inertia_kgm2 is not None:
        _set_key(lines, "rotor", "inertia_kgm2", repr(result.rotor_inertia_kgm2), note)
        _set_key(lines, "rotor", "hforce_N_per_mps", repr(result.hforce_N_per_mps), note)
    atomic.write_text(out, "\n".join(lines) + "\n")
    load_vehicle_file(out, PHYSICS_DT_S)
    return out
