"""``autopilot-sysid``: an autopilot's own identification flight in free flight: the vehicle hovers on the
autopilot's attitude and rate laws (``--controller px4:PARAMS`` or ``ardupilot:PARAMS``; the scenario's default is
that autopilot's defaults) with the altitude held, and the autopilot's excitation is added to the rate set-point
of one axis at a time, roll, pitch, yaw in turn:

- ``autopilot = "px4"``: multicopter autotune's wash-out square wave (:func:`rotorlab.excitation.px4_autotune_signal`,
  amplitude ``MC_AT_SYSID_AMP``), each axis's state ``excite_s`` long and followed by a ``pause_s`` pause state,
  as autotune's roll, roll_pause, pitch, ... states;
- ``autopilot = "ardupilot"``: ArduCopter SYSID mode's chirp on the rate axes (SID_AXIS 7, 8, 9;
  :func:`rotorlab.excitation.ardupilot_sysid_chirp`, ``SID_MAGNITUDE`` in deg/s), each axis one entry into the
  mode: the mode's 1 s delay, then the ``excite_s`` (``SID_T_REC``) record, then ``pause_s`` back in the previous
  mode.

``run.json`` notes hold the plan as flown (``windows``: axis, start and stop of each excitation state, s, cut at the
run's duration; ``rotorlab run --duration`` defaults to the scenario's 37 s, the default plan) and the
excitation's parameters in the autopilot's names (``excitation_params``), so a log exporter
(``rotorlab.twinlogs``) writes the autopilot's own excitation messages.

Options
-------
``autopilot`` : str
    ``px4`` (default) or ``ardupilot``: whose excitation, and whose laws when the run gives no controller.
``axes`` : str
    Comma-separated axes excited in turn (default ``"roll,pitch,yaw"``).
``lead_s`` : float
    Hover before the first axis, s (default 1).
``excite_s`` : float
    Each axis's excitation, s (default 10; ArduPilot's ``SID_T_REC``).
``pause_s`` : float
    The pause after each axis, s (default 2, autotune's pause states).
``sysid_amp_rad_s`` : float
    PX4's ``MC_AT_SYSID_AMP`` (default 0.7, PX4's default).
``sid_magnitude_dps`` : float
    ArduPilot's ``SID_MAGNITUDE`` on the rate axes, deg/s (default 30).
``sid_f_start_hz`` : float
    ArduPilot's ``SID_F_START_HZ`` (default 0.5).
``sid_f_stop_hz`` : float
    ArduPilot's ``SID_F_STOP_HZ`` (default 40).
``sid_t_fade_in_s`` : float
    ArduPilot's ``SID_T_FADE_IN``, s (default 1).
``sid_t_fade_out_s`` : float
    ArduPilot's ``SID_T_FADE_OUT``, s (default 1).
"""

from __future__ import annotations

import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.excitation import ARDUPILOT_SYSID_DELAY_S, ardupilot_sysid_chirp, px4_autotune_signal
from rotorlab.sim.control.autopilot import AutopilotSpec
from rotorlab.sim.scenarios import Context, Setup, merged_options

NAME = "autopilot-sysid"
DESCRIPTION = "an autopilot's identification flight: PX4 autotune's square wave or ArduCopter SYSID's chirp per axis"
SCENES = ("free-flight",)
DURATION_S = 37.0
AXES = ("roll", "pitch", "yaw")
AUTOPILOTS = ("px4", "ardupilot")
DEFAULTS = {"autopilot": "px4", "axes": "roll,pitch,yaw", "lead_s": 1.0, "excite_s": 10.0, "pause_s": 2.0,
            "sysid_amp_rad_s": 0.7, "sid_magnitude_dps": 30.0, "sid_f_start_hz": 0.5, "sid_f_stop_hz": 40.0,
            "sid_t_fade_in_s": 1.0, "sid_t_fade_out_s": 1.0}
# SID_AXIS of the rate axes (ArduCopter mode_systemid.h AxisType: RATE_ROLL = 7, RATE_PITCH, RATE_YAW)
SID_RATE_AXES = {"roll": 7, "pitch": 8, "yaw": 9}


def options(opts: dict) -> dict:
    """The options checked, with ``axes`` as a tuple of axis names."""
    o = dict(opts)
    if o["autopilot"] not in AUTOPILOTS:
        raise ConfigError(field="options.autopilot", expected=f"one of {list(AUTOPILOTS)}", got=o["autopilot"])
    axes = tuple(a.strip() for a in str(o["axes"]).split(",") if a.strip())
    bad = [a for a in axes if a not in AXES]
    if bad or not axes or len(set(axes)) != len(axes):
        raise ConfigError(field="options.axes", expected="distinct names of roll, pitch, yaw, comma-separated",
                          got=o["axes"])
    for key in ("excite_s", "sid_f_start_hz", "sid_f_stop_hz", "sysid_amp_rad_s", "sid_magnitude_dps"):
        if o[key] <= 0:
            raise ConfigError(field=f"options.{key}", expected="a positive number", got=o[key])
    for key in ("lead_s", "pause_s", "sid_t_fade_in_s", "sid_t_fade_out_s"):
        if o[key] < 0:
            raise ConfigError(field=f"options.{key}", expected="a number >= 0", got=o[key])
    if o["autopilot"] == "ardupilot" and o["sid_t_fade_in_s"] + o["sid_t_fade_out_s"] > o["excite_s"]:
        raise ConfigError(field="options.sid_t_fade_in_s", expected="fade-in and fade-out within excite_s (SID_T_REC)",
                          got=(o["sid_t_fade_in_s"], o["sid_t_fade_out_s"], o["excite_s"]))
    o["axes"] = axes
    return o


def plan(o: dict) -> list:
    """``[(axis, start_s, stop_s)]``: each axis's excitation state (PX4: the autotune axis state; ArduPilot: the
    SYSID mode, its 1 s delay included)."""
    state_s = o["excite_s"] + (ARDUPILOT_SYSID_DELAY_S if o["autopilot"] == "ardupilot" else 0.0)
    out, t0 = [], o["lead_s"]
    for axis in o["axes"]:
        out.append((axis, t0, t0 + state_s))
        t0 += state_s + o["pause_s"]
    return out


def flight_s(o: dict) -> float:
    """The flight's length that holds every axis's state and the last pause, s."""
    return plan(o)[-1][2] + o["pause_s"]


def excitation_params(o: dict) -> dict:
    """The excitation's parameters in the autopilot's names and units (what its log records)."""
    if o["autopilot"] == "px4":
        return {"MC_AT_EN": 1, "MC_AT_SYSID_AMP": float(o["sysid_amp_rad_s"])}
    return {"SID_MAGNITUDE": float(o["sid_magnitude_dps"]), "SID_F_START_HZ": float(o["sid_f_start_hz"]),
            "SID_F_STOP_HZ": float(o["sid_f_stop_hz"]), "SID_T_FADE_IN": float(o["sid_t_fade_in_s"]),
            "SID_T_REC": float(o["excite_s"]), "SID_T_FADE_OUT": float(o["sid_t_fade_out_s"])}


def excitation_dps(t_s, o: dict) -> np.ndarray:
    """The rate excitation ``(N, 3)`` (roll, pitch, yaw), deg/s, at times ``t_s`` (s) of the flight."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    out = np.zeros((t.size, 3))
    for axis, t0, t1 in plan(o):
        on = (t >= t0) & (t < t1)
        if not on.any():
            continue
        if o["autopilot"] == "px4":
            v = np.degrees(px4_autotune_signal(t[on] - t0, o["sysid_amp_rad_s"]))
        else:
            v = ardupilot_sysid_chirp(t[on] - t0, o["sid_magnitude_dps"], o["sid_f_start_hz"], o["sid_f_stop_hz"],
                                      o["sid_t_fade_in_s"], o["excite_s"], o["sid_t_fade_out_s"])
        out[on, AXES.index(axis)] = v
    return out


def setup(ctx: Context) -> Setup:
    o = options(merged_options(ctx, DEFAULTS))
    windows = plan(o)

    # the signal on the tick grid, once: the flight software asks for it every tick of the autopilot's loop
    dt = ctx.dt_s
    table = [tuple(row) for row in excitation_dps(dt * np.arange(int(round(ctx.duration_s / dt)) + 2), o).tolist()]
    last = len(table) - 1

    def rate_excitation(t):
        return table[min(int(round(t / dt)), last)]

    # the states the run's duration holds (a shorter run cuts the plan; run.json says what was flown)
    flown = [[a, t0, min(t1, ctx.duration_s)] for a, t0, t1 in windows if t0 < ctx.duration_s]
    notes = {"autopilot": o["autopilot"], "axes": [w[0] for w in flown], "windows": flown,
             "excitation_params": excitation_params(o), "options": {k: v for k, v in o.items() if k != "axes"}}
    return Setup(mode="cascade", altitude_hold=True, rate_excitation=rate_excitation,
                 controller=[AutopilotSpec.from_params(o["autopilot"])],
                 extra_columns={"r_ref": "deg/s", "psi_ref": "deg"}, notes=notes)
