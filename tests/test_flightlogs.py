"""Flight logs in: the readers (walked through their registry), the one table of topic/field names (every row
written and read back), the time-base check, anti-alias resampling, window selection, and the whole path on
logs the project writes itself from a simulated loop with known plant and controller (tests/flightlog_sim.py):
every axis's plant recovered within nu-gap 0.05 of the truth. Bad logs raise DataError naming what is missing.
No test reads ../shared: real logs are for development numbers only."""

import math

import control as ct
import numpy as np
import pytest
from flightlog_sim import (
    ARDUPILOT_UNFILTERED,
    AXES,
    controller,
    dataflash_messages,
    fly,
    px4_params,
    px4_topics,
    true_closed_loop_d,
    true_plant_d,
)

from rotorlab.errors import DataError
from rotorlab.ident.flightlogs import READERS, read_flight_log, time_base_s
from rotorlab.ident.flightlogs.flightlog import quat_to_euler, resample
from rotorlab.ident.flightlogs.identify import identify_direct, identify_plant_indirect
from rotorlab.ident.flightlogs.names import ARDUPILOT_ROWS, PX4_ROWS, SIGNAL_UNITS
from rotorlab.ident.flightlogs.windows import select_windows
from rotorlab.ident.flightlogs.writers import write_dataflash, write_ulog
from rotorlab.ident.metrics import vaf
from rotorlab.ident.nugap import nugap

N = 400
T_US = (1_000_000 + 4000 * np.arange(N)).astype(np.uint64)
EULER = np.column_stack([0.3 * np.sin(np.linspace(0, 6, N)), 0.2 * np.cos(np.linspace(0, 5, N)),
                         1.0 * np.sin(np.linspace(0, 2, N))])


def _euler_to_quat(e):
    r, p, y = (e[:, i] / 2 for i in range(3))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.column_stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def _values(k):
    return 0.5 * np.sin(np.linspace(0, 8, N) + k)  # in the project's unit


# -- the names table, row by row --------------------------------------------------------------------------------

def _row_id(row):
    return f"{row.autopilot}-{row.signal}-{row.topic}-{row.fields[0]}"


def _base_px4(tested):
    """A minimal PX4 log: the rate set-point and measured rate the ``tested`` row does not supply, from rows of
    other topics."""
    topics = {}
    for sig_name in ("rate_sp", "rate"):
        if sig_name == tested.signal:
            continue
        row = next(r for r in PX4_ROWS if r.signal == sig_name and r.topic != tested.topic)
        topics.setdefault(row.topic, {"timestamp": T_US})
        for k, f in enumerate(row.fields):
            topics[row.topic][f] = np.float32(0.1 * (k + 1)) * np.ones(N, np.float32)
    return topics


@pytest.mark.parametrize("row", PX4_ROWS, ids=_row_id)
def test_every_px4_row_is_read(row, tmp_path):
    topics = _base_px4(row)
    if row.kind == "quaternion":
        q = _euler_to_quat(EULER)
        topics[row.topic] = {"timestamp": T_US, **{f: q[:, i].astype(np.float32) for i, f in enumerate(row.fields)}}
        want = EULER
    else:
        topics[row.topic] = {"timestamp": T_US, **{f: (_values(k) / row.scale).astype(np.float32)
                                                   for k, f in enumerate(row.fields)}}
        want = np.column_stack([_values(k) for k in range(3)])
    # the rows before this one for the same signal must not be in the log, else they win
    for other in PX4_ROWS:
        if other.signal == row.signal and other is not row and other.topic != row.topic:
            topics.pop(other.topic, None)
    write_ulog(tmp_path / "row.ulg", topics)
    log = read_flight_log(tmp_path / "row.ulg")
    for k, axis in enumerate(AXES):
        s = log.series(axis, row.signal)
        assert s.unit == SIGNAL_UNITS[row.signal]
        assert row.topic in s.source
        np.testing.assert_allclose(s.values, want[:, k], atol=2e-6)
        np.testing.assert_allclose(s.t_s, T_US * 1e-6)


@pytest.mark.parametrize("row", ARDUPILOT_ROWS, ids=_row_id)
def test_every_ardupilot_row_is_read(row, tmp_path):
    layout = [r for r in ARDUPILOT_ROWS if r.topic == row.topic and r.versions == row.versions]
    cols = ["TimeUS"] + [f for r in layout for f in r.fields]
    vals = {f: _values(k) / r.scale for r in layout for k, f in enumerate(r.fields)}
    rows = [(int(T_US[i]), *(vals[f][i] for f in cols[1:])) for i in range(N)]
    msgs = {row.topic: ("Q" + "f" * (len(cols) - 1), cols, rows)}
    if row.topic != "RATE":
        rate = [(int(T_US[i]), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) for i in range(N)]
        msgs["RATE"] = ("Qfffffffff", ["TimeUS", "RDes", "R", "ROut", "PDes", "P", "POut", "YDes", "Y", "YOut"], rate)
    write_dataflash(tmp_path / "row.bin", msgs)
    log = read_flight_log(tmp_path / "row.bin")
    for k, axis in enumerate(AXES):
        s = log.series(axis, row.signal)
        assert s.unit == SIGNAL_UNITS[row.signal] and f"{row.topic}.{row.fields[k]}" in s.source
        np.testing.assert_allclose(s.values, _values(k), atol=1e-5)


def test_quaternion_to_euler_matches_rotation_matrix():
    q = _euler_to_quat(EULER)
    e = quat_to_euler(q)
    np.testing.assert_allclose(e, EULER, atol=1e-12)


# -- the registry, walked ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def flight():
    return fly(seed=3, excite_s=10.0)


def _write(fmt, f, folder, **kw):
    if fmt == "ulog":
        return write_ulog(folder / "flight.ulg", px4_topics(f, **kw), px4_params(), {"ver_sw_release": 0x010E0000})
    if fmt == "ulog-csv":
        from pyulog.ulog2csv import convert_ulog2csv

        src = write_ulog(folder / "flight.ulg", px4_topics(f, **kw), px4_params())
        out = folder / "csv"
        out.mkdir()
        convert_ulog2csv(str(src), None, str(out), ",", None, None)
        (out / "parameters.csv").write_text("".join(f"{k},{v}\n" for k, v in px4_params().items()))
        return out
    if fmt == "dataflash":
        return write_dataflash(folder / "flight.bin", dataflash_messages(f), {"ATC_RAT_RLL_P": 0.15, **ARDUPILOT_UNFILTERED})
    raise AssertionError(f"no writer for registry entry {fmt}")


@pytest.mark.parametrize("fmt", sorted(READERS))
def test_every_reader_reads_the_simulated_flight(fmt, flight, tmp_path):
    path = _write(fmt, flight, tmp_path)
    log = read_flight_log(path)
    assert log.format == fmt
    assert log.axes == list(AXES)
    for axis in AXES:
        for name in ("rate_sp", "rate", "rate_out"):
            assert name in log.signals[axis]
    # the set-point comes back in rad/s whatever the log's unit (DataFlash: deg/s)
    s = log.series("roll", "rate_sp")
    np.testing.assert_allclose(np.interp(flight.t_loop_s, s.t_s - s.t_s[0], s.values), flight.rate_sp["roll"],
                               atol=1e-5)
    assert [i.label for i in log.excitation] == list(AXES)
    for i, axis in zip(log.excitation, AXES):
        assert i.start_s - log.excitation[0].start_s == pytest.approx(flight.excite_s[axis][0] -
                                                                      flight.excite_s["roll"][0], abs=0.03)
    assert len(log.airborne) == 1 and log.airborne[0].duration_s == pytest.approx(
        flight.t_loop_s[~flight.landed][-1] - flight.t_loop_s[~flight.landed][0], abs=0.2)
    assert log.params  # parameters came through


# -- time base ---------------------------------------------------------------------------------------------------

def test_time_base_detects_units_and_refuses_ambiguity():
    t = np.arange(100) * 0.004
    for scale in (1.0, 1e3, 1e6):  # s, ms, us
        np.testing.assert_allclose(time_base_s(t * scale, None, "x.csv:t"), t)
    # the case: a 250 Hz log stamped in microseconds, declared (or taken) as seconds
    with pytest.raises(DataError, match=r"declared in s give a median sample rate of 0.00025 Hz"):
        time_base_s(t * 1e6, "s", "x.csv:t")
    with pytest.raises(DataError, match=r"declared in us give a median sample rate of 2.5e\+08 Hz"):
        time_base_s(t, "us", "x.csv:t")
    with pytest.raises(DataError, match="cannot tell the time unit"):
        time_base_s(np.arange(100) * 0.1, None, "x.csv:t")  # 10 Hz in s or 10 kHz in ms: ambiguous
    with pytest.raises(DataError, match="backwards"):
        time_base_s([0, 2, 1], "us", "x.csv:t")


def test_resampling_removes_what_would_alias():
    fs_in, fs_out = 500.0, 250.0
    t = np.arange(0, 10, 1 / fs_in)
    slow, fast = np.sin(2 * np.pi * 5 * t), np.sin(2 * np.pi * 200 * t)  # 200 Hz folds to 50 Hz at 250 Hz
    t_new = np.arange(1, 9, 1 / fs_out)
    out_fast = resample(t, fast, t_new, fs_out)
    out_slow = resample(t, slow, t_new, fs_out)
    assert np.std(out_fast) < 0.01  # plain interpolation would leave a 50 Hz alias of amplitude ~1
    assert np.std(np.interp(t_new, t, fast)) > 0.5
    np.testing.assert_allclose(out_slow, np.sin(2 * np.pi * 5 * t_new), atol=0.01)


# -- the whole path against the truth ------------------------------------------------------------------------------

def _identify_axis(log, axis):
    rec = log.record(axis, ("rate_sp", "rate", "rate_out"))
    direct = identify_direct(rec, select_windows(log, rec, "rate_out", "rate"), "plant")
    indirect = identify_plant_indirect(rec, select_windows(log, rec, "rate_sp", "rate"), controller(axis).lti())
    truth = true_plant_d(axis, rec.dt)
    return rec, direct, indirect, truth


@pytest.mark.parametrize("fmt, axes", [("ulog", AXES), ("dataflash", ("roll",))])
def test_simulated_flight_recovers_every_axis_plant(fmt, axes, flight, tmp_path):
    log = read_flight_log(_write(fmt, flight, tmp_path))
    for axis in axes:
        rec, direct, indirect, truth = _identify_axis(log, axis)
        assert rec.dt == pytest.approx(0.004, rel=1e-6)
        # the windows are the autopilot's excitation windows of this axis, less the held-out last 40 %
        exc = next(i for i in log.excitation if i.label == axis)
        assert all(exc.start_s - 1e-9 <= w.start_s and w.stop_s <= exc.stop_s + 1e-9 for w in direct.split.ident)
        assert direct.split.holdout[0].start_s == pytest.approx(exc.start_s + 0.6 * exc.duration_s, abs=0.01)
        # through the known controller the plant is recovered (acceptance: nu-gap 0.05)
        assert nugap(indirect.model.with_delay(), truth) < 0.05, axis
        K, tau = indirect.extra["params"]["K"], indirect.extra["params"]["tau_s"]
        from flightlog_sim import PLANTS

        assert K == pytest.approx(PLANTS[axis][0], rel=0.03) and tau == pytest.approx(PLANTS[axis][1], rel=0.05)
        assert indirect.vaf_holdout > 95
        # and so is it directly (PBSID on the closed-loop record of the rate-loop output)
        assert nugap(direct.model.with_delay(), truth) < 0.05, axis


def test_hand_written_pid_lti_equals_its_step():
    pid = controller("roll")
    rng = np.random.default_rng(0)
    r, y = rng.standard_normal(200), rng.standard_normal(200)
    u_step = np.array([pid.step(a, b) for a, b in zip(r, y)])
    K = controller("roll").lti()
    _, u_lti = ct.forced_response(K, T=np.arange(200) * K.dt, U=np.vstack([r, y]))
    np.testing.assert_allclose(np.ravel(u_lti), u_step, atol=1e-12)


# -- bad logs -----------------------------------------------------------------------------------------------------

def test_truncated_ulog_is_refused(flight, tmp_path):
    path = _write("ulog", flight, tmp_path)
    data = path.read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(data[: len(data) // 2 + 7])
    with pytest.raises(DataError, match="truncated"):
        read_flight_log(cut)
    assert read_flight_log(cut, allow_truncated=True).notes[-1].startswith("truncated")
    head = tmp_path / "head.ulg"
    head.write_bytes(data[:10])
    with pytest.raises(DataError, match="not a ULog"):
        read_flight_log(head)


def test_dataflash_without_rate_is_refused(flight, tmp_path):
    msgs = dataflash_messages(flight)
    del msgs["RATE"]
    write_dataflash(tmp_path / "norate.bin", msgs)
    with pytest.raises(DataError, match="no RATE messages"):
        read_flight_log(tmp_path / "norate.bin")


def test_no_airborne_time_is_refused(flight, tmp_path):
    topics = px4_topics(flight)
    topics["vehicle_land_detected"]["landed"][:] = 1
    write_ulog(tmp_path / "ground.ulg", topics)
    log = read_flight_log(tmp_path / "ground.ulg")
    rec = log.record("roll", ("rate_sp", "rate"))
    with pytest.raises(DataError, match="no airborne time"):
        select_windows(log, rec, "rate_sp", "rate")


def test_no_excitation_is_refused(tmp_path):
    f = fly(seed=1, excite_s=6.0, excite=False)
    write_ulog(tmp_path / "still.ulg", px4_topics(f))
    log = read_flight_log(tmp_path / "still.ulg")
    rec = log.record("pitch", ("rate_sp", "rate"))
    with pytest.raises(DataError, match="no excitation on the pitch axis"):
        select_windows(log, rec, "rate_sp", "rate")


def test_missing_parameter_is_named(flight, tmp_path):
    log = read_flight_log(_write("ulog", flight, tmp_path))
    assert log.param("MC_ROLLRATE_P") == pytest.approx(0.15)
    with pytest.raises(DataError, match="parameter MC_ROLLRATE_K is not in the log"):
        log.param("MC_ROLLRATE_K")


def test_window_override_is_used(flight, tmp_path):
    log = read_flight_log(_write("ulog", flight, tmp_path))
    rec = log.record("roll", ("rate_sp", "rate"))
    split = select_windows(log, rec, "rate_sp", "rate", override=[(4.0, 8.0)])
    assert [(w.start_s, w.stop_s, w.reason) for w in split.ident] == [(4.0, 8.0, "given by the user")]
    assert math.isclose(split.holdout[0].start_s, log.excitation[0].start_s + 0.6 * log.excitation[0].duration_s,
                        abs_tol=0.01)
    with pytest.raises(DataError, match="overlaps the held-out part"):
        select_windows(log, rec, "rate_sp", "rate", override=[(4.0, 10.0)])


def test_airborne_candidates_leave_out_takeoff_and_touchdown(flight, tmp_path):
    from rotorlab.ident.flightlogs.windows import GROUND_GUARD_S, split_windows

    log = read_flight_log(_write("ulog", flight, tmp_path))
    log.excitation = []  # the airborne time is the candidate time
    rec = log.record("roll", ("rate_sp", "rate"))
    ident, held, kind = split_windows(log, rec)
    (air,) = log.airborne
    assert kind.startswith("airborne") and GROUND_GUARD_S > 0
    assert ident[0].start_s == pytest.approx(max(air.start_s, rec.t_s[0]) + GROUND_GUARD_S)
    assert held[-1].stop_s == pytest.approx(min(air.stop_s, rec.t_s[-1] + rec.dt) - GROUND_GUARD_S)


def test_controller_at_another_rate_keeps_the_tustin_law():
    from rotorlab.ident.flightlogs.identify import controller_at

    C = ct.tf([0.003, 0.15, 0.2], [0.002, 1.0, 0.0])  # PID with filtered derivative
    at_1khz = ct.c2d(ct.ss(C), 0.001, method="tustin")
    moved, direct = controller_at(at_1khz, 0.004), ct.c2d(ct.ss(C), 0.004, method="tustin")
    w = np.logspace(-1, 2.5, 30)
    np.testing.assert_allclose(moved(np.exp(1j * w * 0.004)), direct(np.exp(1j * w * 0.004)), rtol=1e-8)


# -- the command line and the report --------------------------------------------------------------------------------

def test_cli_identifies_a_flight_log_and_writes_the_report(flight, tmp_path, capsys):
    import json

    from rotorlab.cli import main

    path = _write("ulog", flight, tmp_path)
    out = tmp_path / "models"
    assert main(["ident", str(path), "--axis", "roll", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "roll  closed-loop" in text and "held-out" in text
    doc = json.loads((out / "roll.json").read_text())
    assert doc["units"] == {"rate_out": "1", "rate": "rad/s"} and doc["input"] == ["rate_out"]
    assert doc["settings"]["extra"]["windows"] and doc["vaf"][0] > 80
    cl = json.loads((out / "roll-closed-loop.json").read_text())
    assert cl["units"] == {"rate_sp": "rad/s", "rate": "rad/s"} and cl["dt"] == pytest.approx(0.004)
    page = (out / "report.html").read_text()
    for png in ("timeline.png", "roll-rates.png", "roll-spectra.png", "roll-fit.png"):
        assert (out / png).stat().st_size > 1000 and png in page
    assert "autopilot excitation window" in page  # the reason each window was chosen


def test_controller_plugs_into_the_run(flight, tmp_path):
    import json

    from rotorlab.ident.flightlogs.run import identify_flight_log

    path = _write("dataflash", flight, tmp_path)
    res = identify_flight_log(path, tmp_path / "m", ["pitch"], controller=lambda log, axis: controller(axis).lti(),
                              report=False)
    m = res.models["pitch"]["plant-indirect"]
    assert nugap(m.model.with_delay(), true_plant_d("pitch", m.dt)) < 0.05
    doc = json.loads((tmp_path / "m" / "pitch.json").read_text())
    assert doc["settings"]["extra"]["kind"] == "plant-indirect"
    assert doc["settings"]["extra"]["params"]["K"] == pytest.approx(350.0, rel=0.03)


@pytest.mark.parametrize("case, expect", [
    ("truncated", "truncated"),
    ("norate", "no RATE messages"),
    ("ground", "no airborne time"),
    ("still", "no excitation on the roll axis"),
])
def test_cli_bad_logs_exit_2_saying_what_is_missing(case, expect, flight, tmp_path, capsys):
    from rotorlab.cli import main

    if case == "truncated":
        data = _write("ulog", flight, tmp_path).read_bytes()
        path = tmp_path / "cut.ulg"
        path.write_bytes(data[: len(data) // 3])
    elif case == "norate":
        msgs = dataflash_messages(flight)
        del msgs["RATE"]
        path = write_dataflash(tmp_path / "norate.bin", msgs)
    elif case == "ground":
        topics = px4_topics(flight)
        topics["vehicle_land_detected"]["landed"][:] = 1
        path = write_ulog(tmp_path / "ground.ulg", topics)
    else:
        path = write_ulog(tmp_path / "still.ulg", px4_topics(fly(seed=1, excite_s=6.0, excite=False)))
    rc = main(["ident", str(path), "--axis", "roll", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2 and expect in err and "Traceback" not in err, err


@pytest.mark.parametrize("release, states", [(0x010E0000, (2, 4, 6)), (0x01110000, (3, 6, 9))])
def test_autotune_state_layout_follows_the_release(release, states, flight, tmp_path):
    """PX4 autotune's excitation states per axis: roll 2, pitch 4, yaw 6 before v1.17; 3, 6, 9 (after the
    amplitude-detection states) from v1.17."""
    topics = px4_topics(flight)
    legacy = topics["autotune_attitude_control_status"]["state"]
    topics["autotune_attitude_control_status"]["state"] = np.select(
        [legacy == 2, legacy == 4, legacy == 6], states, default=0).astype(np.uint8)
    write_ulog(tmp_path / "at.ulg", topics, info={"ver_sw_release": release})
    log = read_flight_log(tmp_path / "at.ulg")
    assert [i.label for i in log.excitation] == list(AXES)
    for i, axis in zip(log.excitation, AXES):
        assert i.duration_s == pytest.approx(np.diff(flight.excite_s[axis])[0], abs=0.03)


def test_dataflash_millisecond_stamps_are_seconds(tmp_path):
    rows = [(1000 + 4 * k, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) for k in range(N)]
    write_dataflash(tmp_path / "ms.bin", {"RATE": ("Ifffffffff", ["TimeMS", "RDes", "R", "ROut", "PDes", "P", "POut",
                                                                  "YDes", "Y", "YOut"], rows)})
    s = read_flight_log(tmp_path / "ms.bin").series("roll", "rate")
    np.testing.assert_allclose(s.t_s, (1000 + 4 * np.arange(N)) * 1e-3)


@pytest.mark.parametrize("fmt", ["ulog", "dataflash"])
def test_damaged_logs_read_or_raise_data_error(fmt, flight, tmp_path):
    """Cut and byte-flipped copies of a log: each reads (pyulog and DFReader skip damaged messages) or raises
    DataError; nothing else escapes to the command line."""
    data = bytearray(_write(fmt, flight, tmp_path).read_bytes())
    rng = np.random.default_rng(7)
    outcomes = set()
    for trial in range(6):
        d = bytearray(data)
        if trial % 3 == 0:
            d = d[: int(rng.integers(0, len(d)))]
        else:
            for i in rng.integers(0, len(d), int(rng.integers(1, 50))):
                d[int(i)] = int(rng.integers(0, 256))
        path = tmp_path / f"damaged{trial}{'.ulg' if fmt == 'ulog' else '.bin'}"
        path.write_bytes(bytes(d))
        try:
            read_flight_log(path, **({"allow_truncated": True} if fmt == "ulog" else {}))
            outcomes.add("read")
        except DataError:
            outcomes.add("DataError")
    assert outcomes == {"read", "DataError"}


def test_raw_gyro_on_a_rotated_board_is_refused(tmp_path):
    topics = {"vehicle_rates_setpoint": {"timestamp": T_US, **{a: np.zeros(N, np.float32) for a in AXES}},
              "sensor_gyro": {"timestamp": T_US, **{f: np.zeros(N, np.float32) for f in ("x", "y", "z")}}}
    write_ulog(tmp_path / "ok.ulg", topics, {"SENS_BOARD_ROT": 0})
    assert read_flight_log(tmp_path / "ok.ulg").series("roll", "rate").source.startswith("sensor_gyro.x")
    write_ulog(tmp_path / "rot.ulg", topics, {"SENS_BOARD_ROT": 2})
    with pytest.raises(DataError, match="SENS_BOARD_ROT = 2"):
        read_flight_log(tmp_path / "rot.ulg")



@pytest.mark.parametrize("rate_every, seed", [(10, 4), (12, 6)])
def test_pilot_flight_at_a_low_log_rate_predicts_like_the_true_loop(rate_every, seed, tmp_path):
    """A pilot-flown ArduCopter log as the Erle-Brain's: stick bursts between quiet stretches longer than a window,
    no SYSID, a torque disturbance, yaw in heading hold (its rate set-point fed back from the measured heading,
    the log's angle P 4.25), RATE at 25 and 20.8 Hz. The direct closed loop is fitted on the whole identification
    part of the airborne time and predicts the held-out part within 2 points of the true rate loop (the plant and
    PID of the simulation, run on the set-point the loop flew at 250 Hz): the most an LTI model of rate_sp -> rate
    reaches, less what 25 Hz samples cannot carry. With the windows cut at the lulls and the candidate ranked by
    its fit on 75 % of one window, these flights' pitch (25 Hz) and roll (20.8 Hz) came 8 and 15 points under."""
    from rotorlab.ident.flightlogs.windows import split_windows

    f = fly(seed=seed, excite_s=25.0, noise=0.05, pilot=True, heading_hold_p=4.25, disturbance=0.02)
    path = write_dataflash(tmp_path / "pilot.bin", dataflash_messages(f, rate_every=rate_every, sysid=False),
                           {"ATC_RAT_RLL_P": 0.15, **ARDUPILOT_UNFILTERED})
    log = read_flight_log(path)
    assert log.excitation == []
    t0_s = 1.0  # dataflash_messages' t0_us
    for axis in AXES:
        rec = log.record(axis, ("rate_sp", "rate"))
        assert rec.dt == pytest.approx(rate_every / 250.0, rel=1e-3)
        split = select_windows(log, rec, "rate_sp", "rate")
        ident, _, _ = split_windows(log, rec)
        assert [(w.start_s, w.stop_s) for w in split.ident] == [(i.start_s, i.stop_s) for i in ident]
        m = identify_direct(rec, split, "closed-loop")
        y_true = ct.forced_response(true_closed_loop_d(axis), U=f.rate_sp[axis]).outputs
        ys, yt = [], []
        for w in split.holdout:
            k = (rec.t_s >= w.start_s) & (rec.t_s < w.stop_s)
            y, p = rec.data["rate"][k], np.interp(rec.t_s[k] - t0_s, f.t_loop_s, y_true)
            ys.append(y - y.mean())
            yt.append(p - p.mean())
        bar = vaf(np.concatenate(ys), np.concatenate(yt))[0] - 2.0
        assert bar > 35.0, axis  # the held-out part carries the pilot's input: the bar is a model's, not noise's
        assert m.vaf_holdout >= bar, (axis, m.vaf_holdout, bar)
