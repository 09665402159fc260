"""The flight software the simulator runs every tick: references, outer loops, attitude cascade, supervisor,
plug-ins, saturation and mixer, in pure Python (no MuJoCo) so it costs microseconds per tick.

Modes
-----
``'cascade'``
    Attitude cascade on roll and pitch to ``phi_ref``/``theta_ref``, heading hold on ``psi_ref``, and
    altitude hold on ``z_ref`` when one is set or ``altitude_hold`` is on (otherwise the collective is ``u_col``).
``'open-loop'``
    Quasi-open-loop identification: on the axes in ``open_loop_axes`` the command is the external command
    (``u_lat``/``u_lon``/``u_yaw`` set by :meth:`FlightSoftware.set_reference`) plus excitation plus, on roll
    and pitch, the :class:`~rotorlab.sim.control.supervisor.Supervisor` output; other axes stay in cascade.
``'position'``
    Position hold (``x_ref``, ``y_ref``) -> roll/pitch set-points, altitude hold (``z_ref``), heading hold.

Signals (units: deg, deg/s, %, m, m/s; frames as in :mod:`rotorlab.sim.control.position`)
------------------------------------------------------------------------------------------
Measurements ``phi, theta, psi, p, q, r`` (always) and ``x, y, z, vx, vy, vz`` (NED; needed for position and
altitude hold). Set-points ``phi_ref, theta_ref, psi_ref, x_ref, y_ref, z_ref``; a missing heading or position
set-point is latched to the measurement at the first tick of the mode. Commands ``u_col`` (collective),
``u_lat`` (roll), ``u_lon`` (pitch), ``u_yaw``; rate set-points ``p_ref, q_ref, r_ref``; supervisor outputs
``sup_lat, sup_lon``; rotor commands ``rotor_pct`` (array, %).

Many simulations
----------------
With ``n`` the same dispatch flies ``n`` simulations at once (:func:`rotorlab.sim.batch.run_batch`): every
measurement, loop state and command is an array ``(n,)``, the loops are those of :mod:`rotorlab.sim.control.vector`
(per-simulation gains, the scalar arithmetic in the same order) and ``rotor_pct`` is ``(n, n_rotors)``. What is
vectorised is what the rig scenarios fly: the cascade and open-loop modes, without position or altitude hold, gain
schedule, excitation or plug-ins (asking for them is a ConfigError).

Excitation
----------
``excitation={'u_lon': array_or_callable, 'theta_ref': ...}`` is added every tick: set-point excitation to the
set-point before the loops, command excitation inside the inner PID before its saturation (so anti-windup sees
it) or to the open-loop command. An array gives element ``k`` on the ``k``-th tick after :meth:`reset` (zero
after its end); a callable is evaluated at ``t``.
"""

from __future__ import annotations

import math

import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.gains import GainSet
from rotorlab.sim.control.cascade import AttitudeController
from rotorlab.sim.control.mixer import Mixer
from rotorlab.sim.control.plugins import Plugin
from rotorlab.sim.control.position import AltitudeHold, PositionGains, PositionHold
from rotorlab.sim.control.supervisor import Supervisor
from rotorlab.sim.control.vector import VectorAttitudeController, VectorSupervisor

MODES = ("cascade", "open-loop", "position")
SETPOINTS = ("phi_ref", "theta_ref", "psi_ref", "x_ref", "y_ref", "z_ref")
COMMANDS = ("u_col", "u_lat", "u_lon", "u_yaw")
#: the rate set-points, which a plug-in flying its own rate loop (``flies_rate_loop``) sets
RATE_REFS = ("p_ref", "q_ref", "r_ref")
AXES = ("roll", "pitch", "yaw")
_AXIS_CMD = {"roll": "u_lat", "pitch": "u_lon", "yaw": "u_yaw"}


def _latch(x):
    """A set-point latched to a measurement: a float, or a copy of the array of many simulations."""
    return float(x) if np.ndim(x) == 0 else np.array(x, dtype=float)


class FlightSoftware:
    """Everything between the sensors and the rotor commands.

    Parameters
    ----------
    gains : rotorlab.gains.GainSet
        Attitude cascade gains.
    mixer : rotorlab.sim.control.mixer.Mixer
    dt : float
        Tick period, s (published: 0.02).
    mode : {'cascade', 'open-loop', 'position'}
    limits : rotorlab.vehicles.spec.CommandLimits
        Roll/pitch and yaw rate set-point and command saturations: the vehicle's ``commands`` (its TOML's
        ``[commands]``), possibly with a scenario's published values over them (``Setup.limits``).
    position_gains : PositionGains, optional
        Outer loops; default ``PositionGains()`` (5 kg, 60 % hover collective).
    supervisor : Supervisor, optional
        Template for the roll and pitch supervisors of open-loop mode (default ``Supervisor()``, +-20 deg).
    open_loop_axes : tuple of str
        Axes that open-loop mode opens (default all three).
    antiwindup : {'clamp', 'backcalc', None}
    schedule : list of (t_s, GainSet), optional
        In-flight gain switches.
    reference : callable t -> dict, optional
        Set-points/external commands by name, evaluated each tick over those of :meth:`set_reference`.
    excitation : dict name -> array or callable, optional
    plugins : sequence of Plugin
    altitude_hold : bool
        Hold the altitude in every mode (``z_ref``, latched to the measurement at the first tick when not set),
        as a pilot's altitude hold under an identification experiment; position mode always holds it.
    n : int, optional
        Fly ``n`` simulations at once (module docstring, "Many simulations"); ``gains`` may then be a sequence of
        n GainSets. None: one simulation, signals are floats.

    Attributes
    ----------
    attitude_by_plugin : bool
        A plug-in sets all three attitude commands itself (an autopilot's own laws,
        :class:`rotorlab.sim.control.autopilot.AutopilotController`): the built-in attitude cascade is then not run
        (its commands would be overwritten), which saves its cost every tick, and the commands the plug-in finds
        are the command excitation alone, plus, in open-loop mode on the opened axes, the external command and the
        supervisor (added to the autopilot's output: closed-loop identification with the autopilot flying). Set
        by the runner when it adds such a plug-in; when it is the only plug-in, the tick calls its ``fly`` with
        the attitude, the set-points, the gyro and those commands as floats
        (:meth:`~rotorlab.sim.control.autopilot.AutopilotController.fly`).
    """

    def __init__(self, gains: GainSet, mixer: Mixer, dt: float = 0.02, mode: str = "cascade", *, limits,
                 position_gains: PositionGains | None = None,
                 supervisor: Supervisor | None = None, open_loop_axes=AXES, antiwindup: str | None = "clamp",
                 schedule=None, reference=None, excitation=None, plugins=(), altitude_hold: bool = False,
                 n: int | None = None):
        if not isinstance(mixer, Mixer):
            raise ConfigError(field="mixer", expected="a rotorlab.sim.control.mixer.Mixer", got=type(mixer).__name__)
        self.dt = float(dt)
        self.mixer = mixer
        self.limits = limits
        self.u_limit_pct = float(limits.limit_pct)
        self.yaw_u_limit_pct = float(limits.yaw_limit_pct)
        self.n = n
        sup = supervisor or Supervisor()
        if n is None:
            self.attitude = AttitudeController(gains, dt, limits, antiwindup, schedule)
            self.sup_roll = Supervisor(sup.limit_deg, sup.engage_frac, sup.kp, sup.kd, sup.u_limit_pct)
            self.sup_pitch = Supervisor(sup.limit_deg, sup.engage_frac, sup.kp, sup.kd, sup.u_limit_pct)
            self._mix = mixer.mix
        else:
            unsupported = [name for name, asked in (("mode 'position'", mode == "position"), ("schedule", schedule),
                                                    ("altitude_hold", altitude_hold),
                                                    ("excitation", excitation), ("plugins", plugins),
                                                    (f"antiwindup '{antiwindup}'", antiwindup != "clamp")) if asked]
            if unsupported:
                raise ConfigError("the flight software of many simulations flies the attitude cascade and the "
                                  "open-loop supervisor only", field="n", expected="one simulation (n=None)",
                                  got=", ".join(unsupported))
            self.attitude = VectorAttitudeController(gains, n, dt, limits)
            self.sup_roll = self.sup_pitch = VectorSupervisor(sup)  # stateless
            self._mix = mixer.mix_many
        self.position_gains = position_gains or PositionGains()
        self.position = PositionHold(self.position_gains, dt)
        self.altitude = AltitudeHold(self.position_gains, dt)
        for ax in open_loop_axes:
            if ax not in AXES:
                raise UnknownNameError("axis", ax, AXES)
        self.open_loop_axes = frozenset(open_loop_axes)
        if reference is not None and not callable(reference):
            raise ConfigError(field="reference", expected="a callable t -> dict", got=type(reference).__name__)
        self.reference = reference
        self.altitude_hold = bool(altitude_hold)
        self.excitation = {}
        for name, sig in (excitation or {}).items():
            if name not in SETPOINTS + COMMANDS:
                raise UnknownNameError("excitation signal", name, SETPOINTS + COMMANDS)
            self.excitation[name] = sig if callable(sig) else np.asarray(sig, dtype=float).ravel().tolist()
        self.plugins = list(plugins)
        self.attitude_by_plugin = False
        for pl in self.plugins:
            if not isinstance(pl, Plugin):
                raise ConfigError(field="plugins", expected="objects with reset() and step(t, signals)",
                                  got=type(pl).__name__)
        self._plugin_signals = set(COMMANDS)  # names a plug-in may set: the commands and its own new signals
        self._ref = {}
        self.set_mode(mode)
        self.reset()

    # ------------------------------------------------------------------ configuration
    def set_mode(self, mode: str) -> None:
        """Change mode; loops that close at the next tick start bumplessly from the last commands."""
        if mode not in MODES:
            raise UnknownNameError("mode", mode, MODES)
        if self.n is not None and hasattr(self, "mode"):
            # the vector loops have no bumpless start
            raise ConfigError("the flight software of many simulations keeps the mode it was built with",
                              field="mode", expected=self.mode, got=mode)
        self.mode = mode
        self._engage = True

    def set_reference(self, **values) -> None:
        """Set set-points and external commands by name (``theta_ref=5.0``, ``u_lon=3.0``; ``None`` clears a
        set-point so it is latched again)."""
        for name, v in values.items():
            if name not in SETPOINTS + COMMANDS:
                raise UnknownNameError("reference", name, SETPOINTS + COMMANDS)
            if v is None:
                self._ref.pop(name, None)
            else:
                self._ref[name] = float(v)

    def reset(self) -> None:
        """Zero every loop, restart the excitation arrays and re-latch missing set-points."""
        self.attitude.reset()
        self.position.reset()
        self.altitude.reset()
        self.sup_roll.reset()
        self.sup_pitch.reset()
        for pl in self.plugins:
            pl.reset()
        self._k = 0
        self._latched = {}
        self._last = {"u_lat": 0.0, "u_lon": 0.0, "u_yaw": 0.0}
        self._engage = False
        self._sig = {}

    # ------------------------------------------------------------------ tick
    def _claim(self, plugin, name: str, sig: dict) -> None:
        """Let ``plugin`` log a new signal ``name``; a name the tick already has (a measurement, a set-point, an
        internal signal) is refused: the plug-in runs after the loops used it, so the value would only replace
        the true signal in the log."""
        if name in sig:
            raise ConfigError(f"plug-in {type(plugin).__name__} returns '{name}', a signal of the flight software",
                              field="outputs", expected=f"commands ({', '.join(COMMANDS)}) or new signal names",
                              got=name)
        self._plugin_signals.add(name)

    def _exc(self, name: str, t: float) -> float:
        sig = self.excitation.get(name)
        if sig is None:
            return 0.0
        if callable(sig):
            return float(sig(t))
        return sig[self._k] if self._k < len(sig) else 0.0

    def _setpoint(self, name: str, refs: dict, sig: dict, meas: str, t: float) -> float:
        """Set-point ``name``: set in ``refs``, else latched to the measurement ``sig[meas]`` (read once, when it
        latches), plus its excitation."""
        v = refs.get(name)
        if v is None:
            v = self._latched.get(name)
            if v is None:
                meas_value = sig.get(meas)
                if meas_value is None:
                    raise ConfigError(f"set-point '{name}' is not set and there is no measurement to latch it to",
                                      field=name[:-4], expected="a measurement in meas")
                v = self._latched[name] = _latch(meas_value)
        return v + (self._exc(name, t) if name in self.excitation else 0.0)

    def _bumpless(self, meas: dict) -> None:
        att = self.attitude
        for ax_name, axis, ang, rate in (("roll", att.roll, "phi", "p"), ("pitch", att.pitch, "theta", "q"),
                                         ("yaw", att.yaw, "psi", "r")):
            axis.reset(self._last[_AXIS_CMD[ax_name]], meas[ang], meas[rate])
        self._latched = {}
        self._engage = False

    def step(self, t: float, meas: dict) -> dict:
        """One tick at time ``t`` (s). Returns a new dict of commands, set-points and internal signals."""
        sig = self._sig
        sig.update(meas)
        self.step_signals(t, sig)
        return dict(sig)

    def step_signals(self, t: float, sig: dict):
        """:meth:`step` in place: ``sig`` holds this tick's measurements and takes the commands, set-points and
        internal signals. The runner keeps one such dict for a whole run (it measures into it, adds the truth
        columns and logs it), so a tick builds and copies no dict. Returns the rotor commands."""
        # written for speed (it runs every tick): locals, one clip per command, no per-tick allocation
        if self._engage:
            self._bumpless(sig)
        refs = self._ref
        if self.reference is not None:
            refs = dict(refs)
            refs.update(self.reference(t))
        exc = self.excitation
        phi, theta, psi = sig["phi"], sig["theta"], sig["psi"]
        p, q, r = sig["p"], sig["q"], sig["r"]
        mode = self.mode

        # outer loops; a set-point set or latched and not excited is looked up in place, without _setpoint's call
        latched = self._latched
        if mode == "position":
            x_ref = refs.get("x_ref", latched.get("x_ref"))
            if x_ref is None or exc:
                x_ref = self._setpoint("x_ref", refs, sig, "x", t)
            y_ref = refs.get("y_ref", latched.get("y_ref"))
            if y_ref is None or exc:
                y_ref = self._setpoint("y_ref", refs, sig, "y", t)
            phi_ref, theta_ref = self.position.step(x_ref, y_ref, sig["x"], sig["y"], sig["vx"], sig["vy"], psi)
            if exc:
                phi_ref += self._exc("phi_ref", t)
                theta_ref += self._exc("theta_ref", t)
            sig["x_ref"], sig["y_ref"] = x_ref, y_ref
        else:
            phi_ref = refs.get("phi_ref", 0.0)
            theta_ref = refs.get("theta_ref", 0.0)
            if exc:
                phi_ref += self._exc("phi_ref", t)
                theta_ref += self._exc("theta_ref", t)
        psi_ref = refs.get("psi_ref", latched.get("psi_ref"))
        if psi_ref is None or exc:
            psi_ref = self._setpoint("psi_ref", refs, sig, "psi", t)
        if mode == "position" or self.altitude_hold or "z_ref" in refs:
            if self.n is not None:
                raise ConfigError("a position or altitude set-point needs the flight software of one simulation",
                                  field="reference", expected="attitude set-points and commands", got=sorted(refs))
            z_ref = refs.get("z_ref", latched.get("z_ref"))
            if z_ref is None or exc:
                z_ref = self._setpoint("z_ref", refs, sig, "z", t)
            u_col = self.altitude.step(-z_ref, -sig["z"], -sig["vz"], phi, theta)
            sig["z_ref"] = z_ref
        else:
            u_col = refs.get("u_col", self.position_gains.hover_collective_pct)
        if exc:
            u_col += self._exc("u_col", t)
            ff_lat, ff_lon, ff_yaw = self._exc("u_lat", t), self._exc("u_lon", t), self._exc("u_yaw", t)
        else:
            ff_lat = ff_lon = ff_yaw = 0.0

        # attitude
        att = self.attitude
        if t >= att.t_next_switch:
            att.apply_schedule(t)
        if mode == "open-loop":
            ol = self.open_loop_axes
            sup_lat = self.sup_roll.step(phi, p) if "roll" in ol else 0.0
            sup_lon = self.sup_pitch.step(theta, q) if "pitch" in ol else 0.0
            by_plugin = self.attitude_by_plugin
            if "roll" in ol:
                u_lat, p_ref = refs.get("u_lat", 0.0) + ff_lat + sup_lat, math.nan
            elif by_plugin:
                u_lat, p_ref = ff_lat, math.nan
            else:
                u_lat, p_ref = att.roll.step(phi_ref, phi, p, ff_lat)
            if "pitch" in ol:
                u_lon, q_ref = refs.get("u_lon", 0.0) + ff_lon + sup_lon, math.nan
            elif by_plugin:
                u_lon, q_ref = ff_lon, math.nan
            else:
                u_lon, q_ref = att.pitch.step(theta_ref, theta, q, ff_lon)
            if "yaw" in ol:
                u_yaw, r_ref = refs.get("u_yaw", 0.0) + ff_yaw, math.nan
            elif by_plugin:
                u_yaw, r_ref = ff_yaw, math.nan
            else:
                u_yaw, r_ref = att.yaw.step(psi_ref, psi, r, ff_yaw)
            sig["sup_lat"], sig["sup_lon"] = sup_lat, sup_lon
        elif self.attitude_by_plugin:
            u_lat, u_lon, u_yaw = ff_lat, ff_lon, ff_yaw
            p_ref = q_ref = r_ref = math.nan
        else:
            u_lat, p_ref = att.roll.step(phi_ref, phi, p, ff_lat)
            u_lon, q_ref = att.pitch.step(theta_ref, theta, q, ff_lon)
            u_yaw, r_ref = att.yaw.step(psi_ref, psi, r, ff_yaw)

        sig["phi_ref"], sig["theta_ref"], sig["psi_ref"] = phi_ref, theta_ref, psi_ref
        plugins = self.plugins
        solo = self.attitude_by_plugin and len(plugins) == 1
        if solo:
            # the autopilot alone (the runner's --controller AUTOPILOT:PARAMS): its floats in and out, no dict
            u_lat, u_lon, u_yaw, p_ref, q_ref, r_ref = plugins[0].fly(
                t, phi, theta, psi, phi_ref, theta_ref, psi_ref, p, q, r, u_lat, u_lon, u_yaw)
        sig["p_ref"], sig["q_ref"], sig["r_ref"] = p_ref, q_ref, r_ref

        if plugins and not solo:
            sig["u_col"], sig["u_lat"], sig["u_lon"], sig["u_yaw"] = u_col, u_lat, u_lon, u_yaw
            own = self._plugin_signals
            for pl in plugins:
                out = pl.step(t, sig)
                if out:
                    for name in out:
                        # an autopilot's rate set-points are the ones its rate loop flew (flies_rate_loop)
                        if name not in own and not (name in RATE_REFS and getattr(pl, "flies_rate_loop", False)):
                            self._claim(pl, name, sig)
                    sig.update(out)
            u_col, u_lat, u_lon, u_yaw = sig["u_col"], sig["u_lat"], sig["u_lon"], sig["u_yaw"]

        lim, ylim, lo, hi = self.u_limit_pct, self.yaw_u_limit_pct, self.mixer.out_min, self.mixer.out_max
        if self.n is None:
            # one simulation: Python comparisons, several times cheaper than np.clip or a call per command
            u_lat = lim if u_lat > lim else (-lim if u_lat < -lim else u_lat)
            u_lon = lim if u_lon > lim else (-lim if u_lon < -lim else u_lon)
            u_yaw = ylim if u_yaw > ylim else (-ylim if u_yaw < -ylim else u_yaw)
            u_col = hi if u_col > hi else (lo if u_col < lo else u_col)
        else:
            u_lat = np.clip(u_lat, -lim, lim)
            u_lon = np.clip(u_lon, -lim, lim)
            u_yaw = np.clip(u_yaw, -ylim, ylim)
            u_col = np.clip(u_col, lo, hi)
        sig["u_col"], sig["u_lat"], sig["u_lon"], sig["u_yaw"] = u_col, u_lat, u_lon, u_yaw
        sig["rotor_pct"] = rotor = self._mix(u_col, u_lat, u_lon, u_yaw)
        last = self._last
        last["u_lat"], last["u_lon"], last["u_yaw"] = u_lat, u_lon, u_yaw
        self._k += 1
        return rotor
