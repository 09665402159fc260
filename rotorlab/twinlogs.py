"""The twin writes its own flights as the autopilots' logs: a PX4 ULog or an ArduPilot DataFlash file of an
identification flight (scenario ``autopilot-sysid``: the autopilot's laws, its excitation on one axis after the
other), so the flight-log path (``rotorlab ident FLIGHT.ulg|FLIGHT.bin``) can be scored against the twin's true
linearisation (:func:`true_rate_plant`).

Topics, messages and fields are those of :mod:`rotorlab.ident.flightlogs.names`; the files are written by
:mod:`rotorlab.ident.flightlogs.writers` (pyulog's writer for ULog; DataFlash packed with pymavlink's format table,
since pymavlink has no DataFlash writer).

What the files hold, per autopilot:

- ULog (PX4 v1.14 layout): ``vehicle_rates_setpoint`` (the rate set-point the rate loop flew, excitation included),
  ``vehicle_angular_velocity`` (the twin's gyro through IMU_GYRO_CUTOFF, as PX4 logs it),
  ``vehicle_torque_setpoint`` (the rate loop's normalised output), ``vehicle_thrust_setpoint``,
  ``vehicle_attitude`` and ``vehicle_attitude_setpoint`` (quaternions), ``vehicle_status`` (armed, ALTCTL),
  ``vehicle_land_detected`` (airborne throughout: the flight starts in hover), ``autotune_attitude_control_status``
  (its state at 10 Hz, the layout before v1.17: 1 init, 2/3 roll and its pause, 4/5 pitch, 6/7 yaw, 11 complete;
  and ``rate_sp``), and the flown parameters with ``MC_AT_*``.
- DataFlash (Copter >= 3.4 layout): ``RATE`` (deg/s, the gyro through INS_GYRO_FILTER; normalised outputs),
  ``ATT`` (deg), ``CTUN.ThO``, ``MODE`` (ALT_HOLD, SYSTEMID per axis), ``EV`` (armed, not landed), ``SIDS`` (the
  SID settings at each mode entry, SID_AXIS 7-9) and ``SIDD`` (every loop while the mode runs), ``PARM`` (flown
  parameters and ``SID_*``).

Both logs carry the loop rate the twin flew as the autopilot's loop-rate parameter (``IMU_GYRO_RATEMAX``,
``SCHED_LOOP_RATE``): the twin flies the laws at its flight-software rate, and the controller rebuilt from the
log must be the one that flew.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rotorlab import autopilots
from rotorlab.autopilots import filters
from rotorlab.errors import ConfigError

__all__ = ["fly_twin_log", "run_to_log", "run_to_ulog", "run_to_dataflash", "log_format", "true_rate_plant",
           "FORMATS", "T0_US", "GYRO_CUTOFF_PARAM"]

#: log suffix -> (format, the autopilot that writes it)
FORMATS = {".ulg": ("ulog", "px4"), ".bin": ("dataflash", "ardupilot")}
#: the log's clock at the twin's t = 0, us (a real log starts at boot, never at 0)
T0_US = 1_000_000
#: the parameter of each autopilot's gyro low-pass, Hz: its logged rate is the filtered gyro its rate law flies on
GYRO_CUTOFF_PARAM = {name: autopilots.get(name).GYRO_FILTER_PARAM for name in ("px4", "ardupilot")}
_D2R = math.pi / 180.0
_AXES = ("roll", "pitch", "yaw")
# PX4 autotune_attitude_control_status.state before v1.17 (msg/AutotuneAttitudeControlStatus.msg)
_PX4_AT_INIT, _PX4_AT_COMPLETE = 1, 11
_PX4_AT_AXIS = {"roll": (2, 3), "pitch": (4, 5), "yaw": (6, 7)}
_PX4_NAV_ALTCTL, _ARMED = 1, 2
_PX4_RELEASE_V1_14 = (1 << 24) | (14 << 16) | 0xFF  # ver_sw_release 0xMMmmppTT, TT = 255: a release
# ArduCopter: mode numbers (ArduCopter/mode.h) and LogEvent ids (AP_Logger)
_AP_ALT_HOLD, _AP_SYSTEMID = 2, 25
_EV_ARMED, _EV_NOT_LANDED = 10, 28
_SID_AXIS = {"roll": 7, "pitch": 8, "yaw": 9}


def true_rate_plant(vehicle, axis: str, dt_s: float, gyro_cutoff_hz: float = 0.0, slow_rad_s: float = 0.1):
    """The twin's true rate plant of ``axis`` in the logs' units: normalised torque (the rate loop's output, 1 =
    a 100 % differential command) in, rad/s out, the command held over ``dt_s`` and the rate sampled at it; with
    ``gyro_cutoff_hz`` the rate as the autopilot logs it, through its gyro low-pass (:data:`GYRO_CUTOFF_PARAM`,
    the second-order filter of :func:`rotorlab.autopilots.filters.butter2_ss` at ``1 / dt_s``).

    From the 1 ms linearisation about hover in free flight (:func:`rotorlab.sim.linearize.linearize`, the rotors'
    transport delays as exact shift registers), with the vehicle's translation held (its position and velocity
    states removed), lifted exactly to ``dt_s`` (a whole number of physics steps) and made minimal; pole/zero pairs
    both within ``slow_rad_s`` of the origin are cancelled (the gain kept at 10 rad/s).

    Why translation is held: in free flight, tilting the thrust accelerates the vehicle and the rotors' speed
    damping turns the speed back into a moment, a slow mode pair (an unstable one near 1.5 rad/s on the
    tuhh-quad's roll and pitch) that a rate-loop record of seconds cannot see and the attitude loop holds. It
    changes the rate response by less than 0.4 % in magnitude and 0.13 rad in phase from 3 rad/s up (0.01 % and
    0.003 rad from 10 rad/s), but an unstable pole pair is decided by the nu-gap's winding-number condition alone
    (any low-order model scores 1). What remains is the rate plant: rotor lags, delays, inertia and the rotors'
    rate damping.

    Examples
    --------
    >>> P = true_rate_plant("tuhh-quad", "roll", 0.004)  # doctest: +SKIP
    >>> float(P.dt)  # doctest: +SKIP
    0.004
    """
    import control as ct
    import mujoco

    from rotorlab.scenes import build_scene
    from rotorlab.sim.linearize import linearize

    sc = build_scene("free-flight", vehicle)
    P1 = linearize(sc, vehicle, input=axis, output=f"gyro_{axis}")
    n = int(round(dt_s / float(P1.dt)))
    if n < 1 or abs(n * float(P1.dt) - dt_s) > 1e-9:
        raise ConfigError(field="dt_s", expected=f"a whole number of physics steps of {float(P1.dt)} s", got=dt_s)
    m = sc.model
    nv = m.nv
    drop = set()
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            a = int(m.jnt_dofadr[j])  # a free joint's first three dofs are its translation
            drop |= {a, a + 1, a + 2, nv + a, nv + a + 1, nv + a + 2}
    A1, B1, C1, D1 = (np.asarray(M, float) for M in (P1.A, P1.B, P1.C, P1.D))
    keep = [i for i in range(A1.shape[0]) if i not in drop]
    A1, B1, C1 = A1[np.ix_(keep, keep)], B1[keep], C1[:, keep]
    A = np.linalg.matrix_power(A1, n)
    B = sum(np.linalg.matrix_power(A1, i) for i in range(n)) @ B1
    # % -> normalised torque (x100 in), deg/s -> rad/s (out)
    P = ct.minreal(ct.ss(A, B * 100.0, C1 * _D2R, D1 * 100.0 * _D2R, dt_s), 1e-7, verbose=False)
    poles = list(np.linalg.eigvals(np.asarray(P.A, float)))
    zeros = list(ct.zeros(P))
    near = lambda z: abs(np.log(complex(z)) / dt_s) < slow_rad_s if abs(z) > 0 else False  # noqa: E731
    dropped = 0
    for pz in [x for x in poles if near(x)]:
        cand = [z for z in zeros if near(z)]
        if cand:
            poles.remove(pz)
            zeros.remove(min(cand, key=lambda z: abs(z - pz)))
            dropped += 1
    if dropped:
        G = ct.tf(np.real(np.poly(zeros)), np.real(np.poly(poles)), dt_s)
        z_ref = np.exp(1j * 10.0 * dt_s)
        k = ct.evalfr(P, z_ref) / ct.evalfr(G, z_ref)
        P = ct.ss(ct.tf(np.real(k) * G.num[0][0], G.den[0][0], dt_s))
    if gyro_cutoff_hz > 0:
        P = ct.series(P, filters.butter2_ss(1.0 / dt_s, gyro_cutoff_hz))
    return P


def _logged_rate(rate_rad_s, autopilot: str, params: dict, dt_s: float) -> np.ndarray:
    """The twin's gyro (rad/s) as the autopilot logs its rate: through the gyro low-pass its rate law ran on it
    (PX4's ``vehicle_angular_velocity`` after IMU_GYRO_CUTOFF, ArduPilot's ``RATE.R`` after INS_GYRO_FILTER), the
    same coefficients from rest, as the law's filter starts after its reset."""
    from scipy.signal import lfilter

    b, a = filters.butter2_coeffs(1.0 / dt_s, float(params[GYRO_CUTOFF_PARAM[autopilot]]))
    return lfilter(b, a, rate_rad_s)


def _notes(result):
    notes = result.info.get("notes") or {}
    if "windows" not in notes or "excitation_params" not in notes:
        raise ConfigError("the run is not an autopilot identification flight", field="scenario",
                          expected="autopilot-sysid", got=result.info.get("scenario"))
    if not notes["windows"]:
        raise ConfigError("the run ended before its first excitation", field="duration_s",
                          expected=f"more than the lead of {notes['options']['lead_s']} s",
                          got=result.info.get("duration_s"))
    return notes


def _flown_params(result) -> dict:
    """The autopilot's parameters as flown: the run's set, its loop-rate parameter at the rate the twin flew, and
    the excitation's parameters."""
    ctl = next((c for c in result.info.get("controller", []) if "autopilot" in c), None)
    if ctl is None:
        raise ConfigError("the run flew no autopilot's laws", field="controller", expected="px4:... or ardupilot:...",
                          got=result.info.get("controller"))
    if ctl["autopilot"] != _notes(result)["autopilot"]:
        raise ConfigError(f"the run flew {ctl['autopilot']}'s laws with {_notes(result)['autopilot']}'s excitation",
                          field="options.autopilot", expected=ctl["autopilot"], got=_notes(result)["autopilot"])
    ap = autopilots.get(ctl["autopilot"])
    params = {k: float(v) for k, v in ctl["params"].items()}
    params[ap.LOOP_RATE_PARAM] = float(round(ctl["loop_hz"]))
    params.update(_notes(result)["excitation_params"])
    return params


def _quat(phi_deg, theta_deg, psi_deg) -> np.ndarray:
    """Z-Y-X Euler angles (deg) -> quaternions ``(N, 4)`` w, x, y, z (PX4's ``q``)."""
    r, p, y = (np.radians(np.asarray(a, float)) / 2 for a in (phi_deg, theta_deg, psi_deg))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.column_stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def _columns(result, params: dict):
    """Time (s) and the run's columns; ``p, q, r`` (deg/s) as the autopilot logs them (:func:`_logged_rate`)."""
    log = result.log
    t = np.asarray(log["t"], float)
    get = {c: np.asarray(log[c], float) for c in ("p", "q", "r", "p_ref", "q_ref", "r_ref", "u_lat", "u_lon",
                                                   "u_yaw", "u_col", "phi", "theta", "psi", "phi_ref",
                                                   "theta_ref", "psi_ref")}
    ap = _notes(result)["autopilot"]
    dt = float(result.info["control_dt_s"])
    for c in ("p", "q", "r"):
        get[c] = _logged_rate(get[c] * _D2R, ap, params, dt) / _D2R
    return t, get


def _flight(result):
    """(scenario notes, flown parameters, time s, columns) of an ``autopilot-sysid`` run, for both writers."""
    notes = _notes(result)  # first: it refuses a run of another scenario
    params = _flown_params(result)
    return (notes, params, *_columns(result, params))


def run_to_ulog(result, path) -> Path:
    """Write an ``autopilot-sysid`` run (a :class:`~rotorlab.sim.runner.RunResult`) as a PX4 ULog at ``path``.

    See the module docstring for the topics. Raises ConfigError for a run of another scenario or without an
    autopilot's laws.

    Examples
    --------
    >>> from rotorlab.sim.runner import run_scenario
    >>> res = run_scenario("autopilot-sysid", "tuhh-quad", options={"axes": "roll"})  # doctest: +SKIP
    >>> run_to_ulog(res, "flight.ulg")  # doctest: +SKIP
    """
    from rotorlab.ident.flightlogs.writers import write_ulog

    notes, params, t, c = _flight(result)
    us = (T0_US + np.round(t * 1e6)).astype(np.uint64)
    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731 - uORB logs floats
    q = _quat(c["phi"], c["theta"], c["psi"])
    qd = _quat(c["phi_ref"], c["theta_ref"], np.nan_to_num(c["psi_ref"]))
    thrust = c["u_col"] / 100.0
    # autotune publishes every 100 ms: its state and signal at that rate
    every = max(1, int(round(0.1 / float(np.median(np.diff(t))))))
    ta = t[::every]
    state = np.full(ta.size, _PX4_AT_INIT, np.uint8)
    for axis, t0, t1 in notes["windows"]:
        on, pause = _PX4_AT_AXIS[axis]
        state[(ta >= t0) & (ta < t1)] = on
        state[(ta >= t1) & (ta < t1 + notes["options"]["pause_s"])] = pause
    state[ta >= notes["windows"][-1][2] + notes["options"]["pause_s"]] = _PX4_AT_COMPLETE
    from rotorlab.sim.scenarios import autopilot_sysid

    opts = dict(notes["options"], axes=tuple(notes["axes"]))
    exc = np.radians(autopilot_sysid.excitation_dps(ta, opts))
    n_slow = ta.size
    topics = {
        "vehicle_rates_setpoint": {"timestamp": us, "roll": f32(c["p_ref"] * _D2R), "pitch": f32(c["q_ref"] * _D2R),
                                   "yaw": f32(c["r_ref"] * _D2R), "thrust_body[0]": f32(0 * thrust),
                                   "thrust_body[1]": f32(0 * thrust), "thrust_body[2]": f32(-thrust)},
        "vehicle_angular_velocity": {"timestamp": us, "xyz[0]": f32(c["p"] * _D2R), "xyz[1]": f32(c["q"] * _D2R),
                                     "xyz[2]": f32(c["r"] * _D2R)},
        "vehicle_torque_setpoint": {"timestamp": us, "xyz[0]": f32(c["u_lat"] / 100), "xyz[1]": f32(c["u_lon"] / 100),
                                    "xyz[2]": f32(c["u_yaw"] / 100)},
        "vehicle_thrust_setpoint": {"timestamp": us, "xyz[0]": f32(0 * thrust), "xyz[1]": f32(0 * thrust),
                                    "xyz[2]": f32(-thrust)},
        "vehicle_attitude": {"timestamp": us, **{f"q[{i}]": f32(q[:, i]) for i in range(4)}},
        "vehicle_attitude_setpoint": {"timestamp": us, **{f"q_d[{i}]": f32(qd[:, i]) for i in range(4)}},
        "vehicle_status": {"timestamp": us[::every], "arming_state": np.full(n_slow, _ARMED, np.uint8),
                           "nav_state": np.full(n_slow, _PX4_NAV_ALTCTL, np.uint8)},
        "vehicle_land_detected": {"timestamp": us[::every], "landed": np.zeros(n_slow, np.uint8)},
        "autotune_attitude_control_status": {"timestamp": us[::every], "state": state,
                                             **{f"rate_sp[{i}]": f32(exc[:, i]) for i in range(3)}},
    }
    info = {"sys_name": "rotorlab twin", "ver_sw": f"rotorlab {result.info.get('vehicle', '')}",
            "ver_sw_release": _PX4_RELEASE_V1_14}
    return write_ulog(path, topics, params, info)


def run_to_dataflash(result, path) -> Path:
    """Write an ``autopilot-sysid`` run as an ArduCopter DataFlash binary log (.bin) at ``path``.

    See the module docstring for the messages.

    Examples
    --------
    >>> res = run_scenario("autopilot-sysid", "tuhh-quad", options={"autopilot": "ardupilot"})  # doctest: +SKIP
    >>> run_to_dataflash(res, "flight.bin")  # doctest: +SKIP
    """
    from rotorlab.ident.flightlogs.writers import write_dataflash

    notes, params, t, c = _flight(result)
    us = (T0_US + np.round(t * 1e6)).astype(np.int64)
    rate_rows = list(zip(us.tolist(), c["p_ref"].tolist(), c["p"].tolist(), (c["u_lat"] / 100).tolist(),
                         c["q_ref"].tolist(), c["q"].tolist(), (c["u_lon"] / 100).tolist(),
                         c["r_ref"].tolist(), c["r"].tolist(), (c["u_yaw"] / 100).tolist()))
    att_rows = list(zip(us.tolist(), c["phi_ref"].tolist(), c["phi"].tolist(), c["theta_ref"].tolist(),
                        c["theta"].tolist(), np.nan_to_num(c["psi_ref"]).tolist(), c["psi"].tolist()))
    ctun_rows = list(zip(us.tolist(), (c["u_col"] / 100).tolist()))
    ep = notes["excitation_params"]
    modes, sids, sidd = [(int(us[0]), _AP_ALT_HOLD, _AP_ALT_HOLD, 0)], [], []
    from rotorlab.sim.scenarios import autopilot_sysid

    opts = dict(notes["options"], axes=tuple(notes["axes"]))
    exc = autopilot_sysid.excitation_dps(t, opts)
    for axis, t0, t1 in notes["windows"]:
        k0 = int(np.searchsorted(t, t0 - 1e-9))
        k1 = int(np.searchsorted(t, t1 - 1e-9))
        if k0 >= t.size:
            break
        modes.append((int(us[k0]), _AP_SYSTEMID, _AP_SYSTEMID, 0))
        # SIDS: the settings written when the mode starts (Copter's Log_Write_SysID_Setup)
        sids.append((int(us[k0]), _SID_AXIS[axis], ep["SID_MAGNITUDE"], ep["SID_F_START_HZ"], ep["SID_F_STOP_HZ"],
                     ep["SID_T_FADE_IN"], 2.0 / ep["SID_F_START_HZ"], ep["SID_T_REC"], ep["SID_T_FADE_OUT"]))
        ax = _AXES.index(axis)
        sidd += [(int(us[k]), float(t[k] - t0), float(exc[k, ax])) for k in range(k0, min(k1, t.size))]
        if k1 < t.size:
            modes.append((int(us[k1]), _AP_ALT_HOLD, _AP_ALT_HOLD, 0))
    messages = {
        "MSG": ("QZ", ["TimeUS", "Message"], [(int(us[0]), "ArduCopter V4.5.0 (rotorlab twin)")]),
        "RATE": ("Qfffffffff", ["TimeUS", "RDes", "R", "ROut", "PDes", "P", "POut", "YDes", "Y", "YOut"], rate_rows),
        "ATT": ("Qffffff", ["TimeUS", "DesRoll", "Roll", "DesPitch", "Pitch", "DesYaw", "Yaw"], att_rows),
        "CTUN": ("Qf", ["TimeUS", "ThO"], ctun_rows),
        "MODE": ("QMBB", ["TimeUS", "Mode", "ModeNum", "Rsn"], modes),
        "EV": ("QB", ["TimeUS", "Id"], [(int(us[0]), _EV_ARMED), (int(us[0]), _EV_NOT_LANDED)]),
        "SIDS": ("QBfffffff", ["TimeUS", "Ax", "Mag", "FSt", "FSp", "TFin", "TC", "TR", "TFout"], sids),
        "SIDD": ("Qff", ["TimeUS", "Time", "Targ"], sidd),
    }
    return write_dataflash(path, messages, params)


def log_format(path, fmt: str | None = None, autopilot: str | None = None) -> tuple[str, str]:
    """``(format, autopilot)`` of a twin log at ``path``: the format from ``fmt`` or the suffix (:data:`FORMATS`), the
    autopilot that writes it; ConfigError for an unknown suffix or format, or an ``autopilot`` that does not write
    that format (the readers take the autopilot from the format).

    Examples
    --------
    >>> log_format("flight.ulg")
    ('ulog', 'px4')
    """
    path = Path(path)
    by_name = {f: ap for f, ap in FORMATS.values()}
    if fmt is None:
        if path.suffix.lower() not in FORMATS:
            raise ConfigError("unknown twin-log format", field="out_path",
                              expected=f"a file ending in {' or '.join(FORMATS)}", got=str(path))
        fmt = FORMATS[path.suffix.lower()][0]
    if fmt not in by_name:
        raise ConfigError(field="fmt", expected=f"one of {sorted(by_name)}", got=fmt)
    if autopilot is not None and autopilot != by_name[fmt]:
        raise ConfigError(f"a {fmt} log is {by_name[fmt]}'s", field="autopilot", expected=by_name[fmt], got=autopilot)
    return fmt, by_name[fmt]


def run_to_log(result, path, fmt: str | None = None) -> Path:
    """Write an ``autopilot-sysid`` run as its autopilot's log: :func:`run_to_ulog` for ``.ulg``,
    :func:`run_to_dataflash` for ``.bin`` (ConfigError when the run flew the other autopilot's laws).

    Examples
    --------
    >>> run_to_log(res, "flight.ulg")  # doctest: +SKIP
    """
    fmt, _ = log_format(path, fmt, _notes(result)["autopilot"])
    return run_to_ulog(result, path) if fmt == "ulog" else run_to_dataflash(result, path)


def fly_twin_log(out_path, vehicle="tuhh-quad", autopilot: str | None = None, params=None,
                 axes=("roll", "pitch", "yaw"), duration_s: float | None = None, seed: int = 0,
                 fmt: str | None = None, options: dict | None = None) -> Path:
    """Fly the twin's identification flight (scenario ``autopilot-sysid``) on an autopilot's laws and write it as
    that autopilot's log.

    Parameters
    ----------
    out_path : str or Path
        ``.ulg`` (PX4 ULog) or ``.bin`` (ArduPilot DataFlash).
    vehicle : str or VehicleSpec
    autopilot : {"px4", "ardupilot"}, optional
        Whose laws and excitation; default: the format's (ULog: px4, DataFlash: ardupilot). A ULog of ArduPilot's
        laws (or the reverse) is refused: the reader takes the autopilot from the format.
    params : dict, optional
        The autopilot's parameters (its names and units); those not given keep the autopilot's defaults.
    axes : sequence of str
        Axes excited in turn.
    duration_s : float, optional
        The whole flight, s: each axis's excitation is what is left after the 1 s lead and a 2 s pause per axis,
        shared equally (ArduPilot: less the SYSID mode's 1 s delay). Default: the scenario's 10 s per axis.
    seed : int
        The twin's sensor-noise seed.
    fmt : {"ulog", "dataflash"}, optional
        Default: from the suffix.
    options : dict, optional
        Further ``autopilot-sysid`` options (amplitudes, chirp frequencies).

    Returns
    -------
    Path
        ``out_path``, written atomically.

    Raises
    ------
    ConfigError
        Unknown format or suffix, an autopilot that does not write that format, a flight too short for its axes.

    Examples
    --------
    >>> from rotorlab.twinlogs import fly_twin_log
    >>> fly_twin_log("twin.ulg", axes=("roll", "pitch", "yaw"), duration_s=30.0)  # doctest: +SKIP
    PosixPath('twin.ulg')
    """
    from rotorlab.sim.control.autopilot import AutopilotSpec
    from rotorlab.sim.runner import run_scenario
    from rotorlab.sim.scenarios import autopilot_sysid

    path = Path(out_path)
    fmt, own = log_format(path, fmt, autopilot)
    autopilot = own
    opts = {**(options or {}), "autopilot": autopilot, "axes": ",".join(axes)}
    o = autopilot_sysid.options({**autopilot_sysid.DEFAULTS, **opts})
    if duration_s is not None:
        delay = autopilot_sysid.ARDUPILOT_SYSID_DELAY_S if autopilot == "ardupilot" else 0.0
        each = (float(duration_s) - o["lead_s"]) / len(o["axes"]) - o["pause_s"] - delay
        if each <= 0:
            raise ConfigError("flight too short for its axes", field="duration_s",
                              expected=f"more than {o['lead_s'] + len(o['axes']) * (o['pause_s'] + delay):g} s",
                              got=duration_s)
        opts["excite_s"] = each
        o = autopilot_sysid.options({**autopilot_sysid.DEFAULTS, **opts})
    spec = AutopilotSpec.from_params(autopilot, params, source="twinlog" if params else "defaults")
    res = run_scenario("autopilot-sysid", vehicle, seed=seed, duration_s=autopilot_sysid.flight_s(o),
                       options=opts, controller=spec)
    if res.stopped:
        raise ConfigError(f"the twin's flight stopped early: {res.stopped}", field="params",
                          expected="laws that fly the vehicle through the excitation", got=spec.name)
    return run_to_log(res, path, fmt)
