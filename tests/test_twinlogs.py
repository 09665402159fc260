"""The twin writes its own flights as the autopilots' logs (rotorlab/twinlogs.py, scenario autopilot-sysid): the
autopilots' excitation signals against the facts read from their sources, the logs read back through the
flight-log readers (excitation windows, parameters, signals in the logs' units), and the plant identified from a
twin-written ULog against the twin's true linearisation (sim/linearize.py, translation held)."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab.errors import ConfigError
from rotorlab.excitation import ARDUPILOT_SYSID_DELAY_S, ardupilot_sysid_chirp, px4_autotune_signal
from rotorlab.ident.flightlogs import read_flight_log
from rotorlab.ident.nugap import chordal_distance, nugap
from rotorlab.sim.scenarios import autopilot_sysid
from rotorlab.twinlogs import GYRO_CUTOFF_PARAM, T0_US, fly_twin_log, true_rate_plant

D2R = math.pi / 180
FLIGHT_S = 45.0  # three axes: 1 s lead, then per axis about 12.7 s of excitation and a 2 s pause
# vehicles/tuhh-quad: the rotors' delay per axis (roll: rotors 2/4, pitch: 1/3) and yaw's spin-up zero q / J_r
DELAY_S = {"roll": 0.024, "pitch": 0.028}
YAW_ZERO_RAD_S = 1.641e-4 / 6.742e-5


def _imu_mount():
    """The twin's IMU mount as its vehicle file describes it (``[imu]``): what a user gives ``rotorlab ident``."""
    from rotorlab.vehicles import load_vehicle

    imu = load_vehicle("tuhh-quad").imu
    return imu.mount_frequency_hz, imu.mount_damping_ratio


def test_px4_autotune_signal_is_the_washed_out_step_sequence():
    amp, dt, tau = 0.7, 0.1, 0.2
    out = px4_autotune_signal(np.arange(80) * dt, amp)
    # undo the wash-out by hand: the low-pass state before sample k is a * sum of the outputs before it
    a = dt / (tau + dt)
    step = out + a * np.concatenate([[0.0], np.cumsum(out)[:-1]])
    np.testing.assert_allclose(np.sort(np.unique(step.round(9))), [0.0, amp], atol=1e-9)
    # level lengths in publications: 6 (the short first step), 10, 9, ... 2, then 6, 5, 4, 3, 2 (mc_autotune's
    # step counter starting at 5 of 10, the maximum counting down to 1 and reset to 5)
    edges = np.flatnonzero(np.diff(step.round(9)) != 0) + 1
    lengths = np.diff(np.concatenate([[0], edges]))
    assert lengths.tolist()[:14] == [6, 10, 9, 8, 7, 6, 5, 4, 3, 2, 6, 5, 4, 3]
    assert step[0] == pytest.approx(amp)
    # held between publications, zero before the state
    t = np.array([-0.01, 0.0, 0.099, 0.1])
    got = px4_autotune_signal(t, amp)
    assert got[0] == 0.0 and got[1] == got[2] == pytest.approx(amp) and got[3] == pytest.approx(amp * (1 - a))


def test_ardupilot_chirp_is_the_sysid_formula():
    mag, f0, f1, fin, rec, fout = 20.0, 0.5, 5.0, 3.0, 30.0, 2.0
    d = ARDUPILOT_SYSID_DELAY_S
    u = lambda t: float(ardupilot_sysid_chirp([t], mag, f0, f1, fin, rec, fout)[0])  # noqa: E731
    assert u(0.5) == 0.0 and u(d) == 0.0 and u(d + rec + 0.1) == 0.0  # the mode's delay; after the record
    # 1.5 s into the fade-in: window 0.5 - 0.5 cos(pi / 2) = 0.5; constant-frequency dwell 2 / f0 = 4 s:
    # sin(pi (1.5 - 4)) = sin(-2.5 pi) = -1
    assert u(d + 1.5) == pytest.approx(-0.5 * mag, rel=1e-9)
    # full amplitude between fades; the sweep starts at phase 0 at the end of the dwell
    assert u(d + 4.0) == pytest.approx(0.0, abs=1e-9)
    t = np.arange(d, d + rec, 1e-4)
    x = ardupilot_sysid_chirp(t, mag, f0, f1, fin, rec, fout)
    assert np.max(np.abs(x)) == pytest.approx(mag, rel=1e-3)
    # the frequency rises exponentially from f0 to f1 over the sweep: half-period spacing of zero crossings
    zc = t[np.flatnonzero(np.diff(np.sign(x)) != 0)]
    late = np.diff(zc[(zc > d + rec - fout - 1.0) & (zc < d + rec - fout)])
    tm = d + rec - fout - 0.5 - d - 4.0
    f_expected = f0 * math.exp(math.log(f1 / f0) * tm / (rec - 4.0))
    assert 1 / (2 * np.mean(late)) == pytest.approx(f_expected, rel=0.05)


def test_rate_excitation_needs_an_autopilot():
    from rotorlab.sim.runner import make_flight_software, resolve_gains
    from rotorlab.sim.scenarios import Setup
    from rotorlab.vehicles import load_vehicle

    v = load_vehicle("tuhh-quad")
    with pytest.raises(ConfigError, match="autopilot's laws"):
        make_flight_software(v, resolve_gains(v, None), Setup(rate_excitation=lambda t: (1.0, 0.0, 0.0)), 1 / 250)


def test_fly_twin_log_refuses_a_format_the_autopilot_does_not_write(tmp_path):
    with pytest.raises(ConfigError, match="dataflash log is ardupilot's"):
        fly_twin_log(tmp_path / "x.bin", autopilot="px4")
    with pytest.raises(ConfigError, match="unknown twin-log format"):
        fly_twin_log(tmp_path / "x.csv")
    with pytest.raises(ConfigError, match="too short"):
        fly_twin_log(tmp_path / "x.ulg", duration_s=5.0)


@pytest.fixture(scope="module")
def px4_flight(tmp_path_factory):
    path = fly_twin_log(tmp_path_factory.mktemp("twin") / "twin.ulg", duration_s=FLIGHT_S, seed=0)
    return path, read_flight_log(path)


def _plan(autopilot, duration_s, axes=("roll", "pitch", "yaw")):
    o = autopilot_sysid.options({**autopilot_sysid.DEFAULTS, "autopilot": autopilot, "axes": ",".join(axes)})
    delay = ARDUPILOT_SYSID_DELAY_S if autopilot == "ardupilot" else 0.0
    o["excite_s"] = (duration_s - o["lead_s"]) / len(axes) - o["pause_s"] - delay
    return autopilot_sysid.plan(o)


def test_twin_ulog_reads_back_with_its_autotune_windows_and_parameters(px4_flight):
    _, log = px4_flight
    assert log.autopilot == "px4" and log.version == "v1.14.0" and log.axes == ["roll", "pitch", "yaw"]
    t0 = T0_US * 1e-6
    for got, (axis, start, stop) in zip(log.excitation, _plan("px4", FLIGHT_S)):
        assert got.label == axis
        # autotune's state is published every 100 ms: a window ends at most one publication late
        assert got.start_s == pytest.approx(t0 + start, abs=0.11) and got.stop_s == pytest.approx(t0 + stop, abs=0.11)
    assert log.params["IMU_GYRO_RATEMAX"] == 250.0  # the loop rate the twin flew, not the 400 Hz default
    assert log.params["MC_AT_SYSID_AMP"] == pytest.approx(0.7) and log.params["MC_ROLLRATE_P"] == pytest.approx(0.15)
    assert log.airborne and log.airborne[0].start_s == pytest.approx(t0, abs=0.01)
    # the rate set-point carries the excitation: in the roll state its spread is the square wave's
    sp = log.series("roll", "rate_sp")
    on = (sp.t_s > t0 + 2.0) & (sp.t_s < t0 + 8.0)
    assert 0.15 < np.std(sp.values[on]) < 0.7
    assert log.series("roll", "rate_out").unit == "1" and log.series("roll", "rate").unit == "rad/s"


@pytest.fixture(scope="module")
def px4_models(px4_flight, tmp_path_factory):
    from rotorlab.ident.flightlogs.run import identify_flight_log

    path, _ = px4_flight
    return identify_flight_log(path, tmp_path_factory.mktemp("models"), report=False, imu_mount=_imu_mount())


def _truth(res, axis):
    log, m = res.log, res.models[axis]["closed-loop"]
    return true_rate_plant("tuhh-quad", axis, m.dt, log.params[GYRO_CUTOFF_PARAM[log.autopilot]])


@pytest.mark.parametrize("axis", ["roll", "pitch"])
def test_twin_ulog_plant_through_the_controller_is_the_twins_true_linearisation(axis, px4_models):
    """``rotorlab ident``'s path on the twin-written ULog: the plant (rate-loop output -> logged rate) recovered
    through PX4's rate law rebuilt from the log's parameters, against the twin's true rate plant through the same
    gyro low-pass (IMU_GYRO_CUTOFF, in the structure as the log's filter) and the IMU mount of the vehicle file.
    Measured at seeds 0-2: nu-gap 0.004-0.009 on roll and pitch (0.024-0.027 without the mount), K within 0.5 % of
    the truth's gain at 1 rad/s, the motor lag within 2 % of the vehicle file's 0.0369 s, the delay within 0.5 ms
    of its 24 / 28 ms."""
    m = px4_models.models[axis]["plant-indirect"]
    truth = _truth(px4_models, axis)
    assert nugap(m.model.with_delay(), truth) < 0.02
    K, tau = m.extra["params"]["K"], m.extra["params"]["tau_s"]
    assert K == pytest.approx(abs(ct.evalfr(truth, np.exp(1j * m.dt))), rel=0.02)
    assert tau == pytest.approx(0.0369, rel=0.05)  # vehicles/tuhh-quad lag_s
    assert m.extra["params"]["delay_s"] == pytest.approx(DELAY_S[axis], abs=0.0015)
    assert m.vaf_holdout > 95


def _yaw_physics(m, res):
    """The yaw structure's physics: the spin-up zero q / J_r of the vehicle file; two motor paths, the lag and
    delay of the roll fit (rotors 2/4) and of the pitch fit (rotors 1/3)."""
    p = m.extra["params"]
    assert p["z_rad_s"] == pytest.approx(YAW_ZERO_RAD_S, rel=0.2)
    for axis, (lag, delay) in zip(("roll", "pitch"), (("tau_s", "delay_s"), ("tau2_s", "delay2_s"))):
        fit = res.models[axis]["plant-indirect"].extra["params"]
        assert (p[lag], p[delay]) == (fit["tau_s"], fit["delay_s"])


def test_twin_ulog_yaw_plant_matches_the_truth_where_the_log_holds_it(px4_models):
    """Yaw from the ULog through PX4's law: the yaw structure (drag pole, spin-up zero, the motors of roll and
    pitch, the gyro filter, the IMU mount) within chordal distance 0.03 of the twin's true linearisation up to
    100 rad/s (measured 0.019 at seeds 0-2)."""
    m = px4_models.models["yaw"]["plant-indirect"]
    w = np.logspace(-1, 2, 200)
    assert np.max(chordal_distance(m.model.with_delay(), _truth(px4_models, "yaw"), w)) < 0.03
    _yaw_physics(m, px4_models)
    assert m.vaf_holdout > 95


def test_twin_ulog_yaw_plant_is_the_twins_true_linearisation(px4_models):
    """The whole band: nu-gap 0.026-0.028 at seeds 0-2 (0.18 without the mount: PX4's 40 Hz gyro filter passes
    the mount's 58.7 Hz mode, where the yaw plant's gain is 0.23 and a yaw record, behind MC_YAW_TQ_CUTOFF's 2 Hz
    low-pass, holds no information; 0.06 at seed 0 with the mount but one motor path at the mean of 24 and 28 ms:
    at 55 Hz the two paths' mean is 23 % below it in gain)."""
    m = px4_models.models["yaw"]["plant-indirect"]
    assert nugap(m.model.with_delay(), _truth(px4_models, "yaw")) < 0.05


def test_cli_ident_takes_the_imu_mount(px4_flight, tmp_path, capsys):
    """``rotorlab ident FLIGHT.ulg --imu-mount HZ,DAMPING``: the mount in the written plant model; a malformed
    value exits 2 naming the option, what it expects and what it got."""
    import json

    from rotorlab.cli import main

    path, _ = px4_flight
    hz, zeta = _imu_mount()
    assert main(["ident", str(path), "--axis", "roll", "--imu-mount", f"{hz},{zeta}", "--out", str(tmp_path / "m")]) == 0
    params = json.loads((tmp_path / "m" / "roll.json").read_text())["settings"]["extra"]["params"]
    assert (params["mount_hz"], params["mount_zeta"]) == (hz, zeta)
    capsys.readouterr()
    assert main(["ident", str(path), "--imu-mount", "60", "--out", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err
    assert "--imu-mount expects HZ,DAMPING" in err and "'60'" in err and "Traceback" not in err


AP_OPTIONS = {"sid_f_start_hz": 1.0, "sid_magnitude_dps": 20.0}


@pytest.fixture(scope="module")
def ap_flight(tmp_path_factory):
    # SYSID's chirp from 1 Hz at 20 deg/s: a 0.5 Hz start at 30 deg/s swings the free-flying vehicle into its slow
    # translational modes (below 1.5 rad/s), which the rate plant's structure does not hold (roll nu-gap 0.069); a
    # 2 Hz start (12.6 rad/s) leaves yaw's drag pole (0.41 1/s) and spin-up zero (2.4 1/s) below the excited band
    # (yaw nu-gap 0.050-0.075, the pole fitted at its bound 0)
    path = fly_twin_log(tmp_path_factory.mktemp("twin") / "twin.bin", duration_s=FLIGHT_S, seed=0, options=AP_OPTIONS)
    return path, read_flight_log(path)


def test_twin_dataflash_reads_back_with_its_sysid_windows(ap_flight):
    _, log = ap_flight
    assert log.autopilot == "ardupilot" and log.axes == ["roll", "pitch", "yaw"]
    t0 = T0_US * 1e-6
    plan = _plan("ardupilot", FLIGHT_S)
    assert [i.label for i in log.excitation] == ["roll", "pitch", "yaw"]
    for got, (_, start, stop) in zip(log.excitation, plan):
        # SIDD every loop (4 ms) while the mode runs, its 1 s delay included; its axis from SIDS.Ax (7-9)
        assert got.start_s == pytest.approx(t0 + start, abs=0.005) and got.stop_s == pytest.approx(t0 + stop, abs=0.01)
    assert [m.label for m in log.modes] == ["ALT_HOLD", "SYSTEMID"] * 3 + ["ALT_HOLD"]
    assert log.params["SID_T_REC"] == pytest.approx(plan[0][2] - plan[0][1] - ARDUPILOT_SYSID_DELAY_S)
    assert log.params["SID_F_START_HZ"] == 1.0 and log.params["SCHED_LOOP_RATE"] == 250.0
    # RATE in deg/s read as rad/s: the set-point's swing in the chirp is the chirp's 20 deg/s and the attitude hold's
    # share (30 deg/s in all from a 1 Hz start at seed 0); a unit slip would be 57 times off
    sp = log.series("roll", "rate_sp")
    on = (sp.t_s > t0 + plan[0][1] + 5.0) & (sp.t_s < t0 + plan[0][2] - 2.0)
    assert 0.5 * 20 * D2R < np.max(np.abs(sp.values[on])) < 2.0 * 20 * D2R


@pytest.fixture(scope="module")
def ap_models(ap_flight, tmp_path_factory):
    from rotorlab.ident.flightlogs.run import identify_flight_log

    return identify_flight_log(ap_flight[0], tmp_path_factory.mktemp("models"), report=False, imu_mount=_imu_mount())


@pytest.mark.parametrize("axis", ["roll", "pitch"])
def test_twin_dataflash_plant_through_the_controller_is_the_twins_true_linearisation(axis, ap_models):
    """The same from the twin-written DataFlash file, through ArduPilot's AC_PID rebuilt from its PARM messages,
    INS_GYRO_FILTER's 20 Hz low-pass and the vehicle file's IMU mount in the structure: measured nu-gaps
    0.009-0.018 (roll) and 0.012-0.020 (pitch) at seeds 0-2, the delay within 0.3 ms of the vehicle file's."""
    m = ap_models.models[axis]["plant-indirect"]
    assert nugap(m.model.with_delay(), _truth(ap_models, axis)) < 0.05
    assert m.extra["params"]["tau_s"] == pytest.approx(0.0369, rel=0.05)
    assert m.extra["params"]["delay_s"] == pytest.approx(DELAY_S[axis], abs=0.0015)


def test_twin_dataflash_yaw_plant_is_the_twins_true_linearisation(ap_models):
    """Yaw from the DataFlash file through AC_PID: the yaw structure (two motor paths, the IMU mount) within
    nu-gap 0.05 of the twin's true linearisation: measured 0.012-0.019 at seeds 0-2, the spin-up zero within 4 %
    of q / J_r."""
    m = ap_models.models["yaw"]["plant-indirect"]
    assert nugap(m.model.with_delay(), _truth(ap_models, "yaw")) < 0.05
    _yaw_physics(m, ap_models)


def test_cli_run_writes_the_autopilot_log_and_refuses_a_mismatch(tmp_path, capsys):
    from rotorlab.cli import main

    base = ["run", "autopilot-sysid", "--vehicle", "tuhh-quad", "--duration", "4", "--option", "axes=roll",
            "--option", "excite_s=2.0", "--json"]
    ulg = tmp_path / "twin.ulg"
    assert main([*base, "--controller", "px4:defaults", "--out", str(tmp_path / "r1"), "--autopilot-log", str(ulg)]) == 0
    log = read_flight_log(ulg)
    assert [i.label for i in log.excitation] == ["roll"] and log.params["MC_AT_SYSID_AMP"] == pytest.approx(0.7)
    capsys.readouterr()
    # a bad name is refused before the flight; PX4's laws with ArduPilot's chirp make no DataFlash log
    assert main([*base, "--out", str(tmp_path / "r2"), "--autopilot-log", str(tmp_path / "twin.csv")]) == 2
    assert "--autopilot-log" in capsys.readouterr().err
    assert main([*base, "--controller", "px4:defaults", "--option", "autopilot=ardupilot", "--out",
                 str(tmp_path / "r3"), "--autopilot-log", str(tmp_path / "twin.bin")]) == 2
    err = capsys.readouterr().err
    assert "flew px4's laws with ardupilot's excitation" in err and "Traceback" not in err
    assert not (tmp_path / "twin.bin").exists()


def test_a_run_shorter_than_the_plan_logs_what_it_flew(tmp_path):
    from rotorlab.sim.runner import run_scenario
    from rotorlab.twinlogs import run_to_ulog

    res = run_scenario("autopilot-sysid", "tuhh-quad", duration_s=5.0, options={"excite_s": 3.0})
    assert res.info["notes"]["windows"] == [["roll", 1.0, 4.0]]  # pitch would start at 6 s
    assert [i.label for i in read_flight_log(run_to_ulog(res, tmp_path / "a.ulg")).excitation] == ["roll"]
    res = run_scenario("autopilot-sysid", "tuhh-quad", duration_s=0.5)
    with pytest.raises(ConfigError, match="before its first excitation"):
        run_to_ulog(res, tmp_path / "b.ulg")
