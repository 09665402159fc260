"""The autopilots' controller laws (rotorlab.autopilots) against hand-computed responses of the documented laws,
their LTI forms against the stateful steps, the filters against their defining formulas, and the parameter files."""

import itertools
import math

import control as ct
import numpy as np
import pytest
import scipy.signal as sig

from rotorlab import autopilots
from rotorlab.autopilots import ardupilot, filters, px4
from rotorlab.errors import ConfigError, DataError, UnknownNameError

DT = 1 / 400


def _lsim(sys, u):
    """Discrete simulation from zero state: ``u`` is (n, inputs)."""
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    x = np.zeros(A.shape[0])
    out = []
    for uk in u:
        out.append(C @ x + D @ uk)
        x = A @ x + B @ uk
    return np.array(out)


# ---------------------------------------------------------------- filters

@pytest.mark.parametrize("fs, fc", [(400.0, 40.0), (250.0, 20.0), (1000.0, 30.0), (400.0, 150.0)])
def test_butter2_is_scipys_prewarped_butterworth_and_is_3db_down_at_its_cutoff(fs, fc):
    b, a = filters.butter2_coeffs(fs, fc)
    bs, as_ = sig.butter(2, fc, btype="low", fs=fs)  # bilinear with pre-warping: the same design
    np.testing.assert_allclose(b, bs, rtol=1e-12)
    np.testing.assert_allclose(a, as_, rtol=1e-12, atol=1e-15)
    H = ct.evalfr(filters.butter2_ss(fs, fc), np.exp(2j * np.pi * fc / fs))
    assert abs(abs(H) - 1 / math.sqrt(2)) < 1e-12
    assert abs(ct.evalfr(filters.butter2_ss(fs, fc), 1.0) - 1.0) < 1e-12


@pytest.mark.parametrize("fc", [0.0, -1.0, 200.0, 250.0])
def test_butter2_is_off_at_zero_or_above_nyquist(fc):
    G = filters.butter2_ss(400.0, fc)
    assert G.nstates == 0 and float(G.D[0, 0]) == 1.0


def test_butter2_state_space_runs_the_difference_equation():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(300)
    y = _lsim(filters.butter2_ss(400.0, 40.0), u[:, None])[:, 0]
    np.testing.assert_allclose(y, sig.lfilter(*filters.butter2_coeffs(400.0, 40.0), u), atol=1e-13)


@pytest.mark.parametrize("fs, fc", [(400.0, 2.0), (400.0, 20.0), (250.0, 2.5)])
def test_alpha_filter_gain_and_its_3db_frequency_from_the_formula(fs, fc):
    dt = 1 / fs
    a = dt / (dt + 1 / (2 * math.pi * fc))
    assert filters.alpha_lowpass(dt, fc) == pytest.approx(a, rel=1e-15)
    # |a / (1 - (1-a) e^{-j theta})|^2 = 1/2  <=>  cos(theta) = (1 + b^2 - 2 a^2) / (2 b), b = 1 - a
    b = 1 - a
    f3 = math.acos((1 + b * b - 2 * a * a) / (2 * b)) * fs / (2 * math.pi)
    G = filters.alpha_ss(dt, fc)
    assert abs(abs(ct.evalfr(G, np.exp(2j * np.pi * f3 / fs))) - 1 / math.sqrt(2)) < 1e-12
    # a backward-Euler RC: -3 dB below its nominal cutoff (17.5 Hz for 20 Hz at 400 Hz), close to it for fc << fs
    assert f3 < fc
    if fc / fs <= 0.005:
        assert f3 == pytest.approx(fc, rel=0.02)
    y = _lsim(G, np.ones((5, 1)))[:, 0]  # y[k] = y[k-1] + a (1 - y[k-1]) from y[-1] = 0
    np.testing.assert_allclose(y, 1 - b ** np.arange(1, 6), rtol=1e-14)


# ---------------------------------------------------------------- PX4 rate law by hand

def _px4(**over):
    p = px4.TABLE.defaults()
    p.update(over)
    return p


def test_px4_rate_step_without_feed_forward_by_hand():
    p = _px4(IMU_GYRO_CUTOFF=0.0)  # raw gyro = filtered gyro: the hand computation needs no filter state
    rc = px4.RateController(p, DT)
    r, n = 0.1, 6
    u = np.array([rc.step([r, r, r], [0.0] * 3) for _ in range(n)])
    f = 1 - (r / math.radians(400)) ** 2  # PX4's i_factor
    for ax, name in enumerate(("ROLLRATE", "PITCHRATE")):
        kp, ki = p[f"MC_{name}_P"], p[f"MC_{name}_I"]
        np.testing.assert_allclose(u[:, ax], kp * r + ki * f * r * DT * np.arange(n), rtol=1e-14)
    # yaw: the same PI through the 2 Hz torque low-pass, y[k] = y[k-1] + alpha (v[k] - y[k-1])
    a = DT / (DT + 1 / (2 * math.pi * 2.0))
    y, want = 0.0, []
    for k in range(n):
        y += a * (p["MC_YAWRATE_P"] * r + p["MC_YAWRATE_I"] * f * r * DT * k - y)
        want.append(y)
    np.testing.assert_allclose(u[:, 2], want, rtol=1e-13)


def test_px4_feed_forward_and_k_scaling_by_hand():
    p = _px4(IMU_GYRO_CUTOFF=0.0, MC_ROLLRATE_FF=0.05, MC_ROLLRATE_K=2.0, MC_ROLLRATE_P=0.1, MC_ROLLRATE_I=0.3)
    rc = px4.RateController(p, DT)
    r = 0.2
    u0 = rc.step([r, 0, 0], [0.0] * 3)[0]
    u1 = rc.step([r, 0, 0], [0.0] * 3)[0]
    f = 1 - (r / math.radians(400)) ** 2
    assert u0 == pytest.approx(2.0 * 0.1 * r + 0.05 * r, rel=1e-14)  # K scales P, not FF
    assert u1 - u0 == pytest.approx(2.0 * 0.3 * f * r * DT, rel=1e-12)  # K scales I


def test_px4_no_derivative_kick_on_a_set_point_step_but_on_a_measurement_step():
    p = _px4(IMU_GYRO_CUTOFF=0.0, IMU_DGYRO_CUTOFF=0.0, MC_ROLLRATE_D=0.01, MC_ROLLRATE_I=0.0)
    rc = px4.RateController(p, DT)
    u = rc.step([1.0, 0, 0], [0.0] * 3)[0]
    assert u == pytest.approx(p["MC_ROLLRATE_P"] * 1.0, rel=1e-14)  # P only: D sees the measurement, not r
    rc.reset()
    u = rc.step([0.0] * 3, [0.5, 0, 0])[0]
    assert u == pytest.approx(-p["MC_ROLLRATE_P"] * 0.5 - 0.01 * 0.5 / DT, rel=1e-14)
    u = rc.step([0.0] * 3, [0.5, 0, 0])[0]
    assert u == pytest.approx(-p["MC_ROLLRATE_P"] * 0.5, rel=1e-14)  # constant rate: derivative back to zero


def test_px4_integrator_limit_i_factor_and_saturation_flags():
    p = _px4(IMU_GYRO_CUTOFF=0.0, MC_ROLLRATE_I=5.0, MC_RR_INT_LIM=0.1, MC_ROLLRATE_D=0.0)
    rc = px4.RateController(p, DT)
    e = math.radians(200)
    rc.step([e, 0, 0], [0.0] * 3)
    assert rc.integral[0] == pytest.approx(0.75 * 5.0 * e * DT, rel=1e-12)  # i_factor 1 - (200/400)^2
    for _ in range(200):
        u = rc.step([e, 0, 0], [0.0] * 3)
    assert rc.integral[0] == 0.1
    assert u[0] == pytest.approx(p["MC_ROLLRATE_P"] * e + 0.1, rel=1e-14)
    rc.reset()
    rc.step([0.1, 0, 0], [0.0] * 3, sat_pos=[True, False, False])
    assert rc.integral[0] == 0.0  # saturated upwards: a positive error cannot grow the integrator
    rc.step([-0.1, 0, 0], [0.0] * 3, sat_pos=[True, False, False])
    assert rc.integral[0] < 0.0
    rc.reset()
    rc.step([0.1, 0, 0], [0.0] * 3, landed=True)
    assert rc.integral[0] == 0.0


@pytest.mark.parametrize("axis", px4.AXES)
@pytest.mark.parametrize("gyro_filter", [True, False])
def test_px4_lti_form_equals_the_stateful_law_below_saturation(axis, gyro_filter):
    p = _px4(MC_ROLLRATE_FF=0.02, MC_PITCHRATE_D=0.004, MC_YAWRATE_D=0.001)
    rng = np.random.default_rng(7)
    n = 800
    r = 0.01 * np.cumsum(rng.standard_normal(n)) / 10
    y = 0.01 * rng.standard_normal(n)
    ax = px4.AXES.index(axis)
    rc = px4.RateController(p, DT, gyro_filter=gyro_filter)
    got, err = [], []
    for k in range(n):
        rv, yv = np.zeros(3), np.zeros(3)
        rv[ax], yv[ax] = r[k], y[k]
        got.append(rc.step(rv, yv)[ax])
        err.append(rc.rate_error[ax])
    want = _lsim(px4.rate_controller_lti(p, axis, DT, gyro_filter=gyro_filter), np.c_[r, y])[:, 0]
    # the only nonlinearity below saturation is i_factor = 1 - (e / 400 deg/s)^2: the integrator of the law lags
    # the LTI one by at most sum K I dt |e|^3 / (400 deg/s)^2 (the yaw low-pass has unit gain and cannot add to it)
    ki = p[f"MC_{axis.upper()}RATE_I"] * p[f"MC_{axis.upper()}RATE_K"]
    bound = np.r_[0.0, np.cumsum(ki * DT * np.abs(err) ** 3 / math.radians(400) ** 2)[:-1]]
    assert np.max(bound) < 1e-4 * np.max(np.abs(want))
    assert np.all(np.abs(np.array(got) - want) <= bound * (1 + 1e-6) + 1e-15)


# ---------------------------------------------------------------- PX4 attitude law

def test_px4_attitude_law_small_errors_yaw_weight_and_rate_limit():
    p = px4.TABLE.defaults()
    att = px4.AttitudeController(p)
    for ax, gain in enumerate(("MC_ROLL_P", "MC_PITCH_P", "MC_YAW_P")):
        th = 0.02
        qs = np.zeros(4)
        qs[0], qs[1 + ax] = math.cos(th / 2), math.sin(th / 2)
        rate = att.update([1, 0, 0, 0], qs)
        # roll/pitch: 2 sin(th/2) P; yaw: 2 sin(w th/2) P / w (the yaw weight w undone on the gain)
        w = 1.0 if ax < 2 else p["MC_YAW_WEIGHT"]
        assert rate[ax] == pytest.approx(2 * math.sin(w * th / 2) * p[gain] / w, rel=1e-9)
        assert np.allclose(np.delete(rate, ax), 0.0, atol=1e-12)
        lti = px4.attitude_controller_lti(p, px4.AXES[ax], DT)
        assert rate[ax] == pytest.approx(float(lti.D[0, 0]) * th, rel=1e-4)
    th = 1.2  # 2 sin(0.6) 4 = 4.5 rad/s asked for, 220 deg/s = 3.84 rad/s allowed
    rate = att.update([1, 0, 0, 0], [math.cos(th / 2), math.sin(th / 2), 0, 0])
    assert rate[0] == pytest.approx(math.radians(220.0), rel=1e-12)


# ---------------------------------------------------------------- ArduPilot AC_PID by hand

def _ap(**over):
    p = ardupilot.TABLE.defaults()
    p.update(over)
    return p


def test_ardupilot_rate_step_with_and_without_feed_forward_by_hand():
    p = _ap(INS_GYRO_FILTER=0.0, ATC_RAT_RLL_FLTT=0.0, ATC_RAT_RLL_FLTE=0.0, ATC_RAT_RLL_D=0.0,
            ATC_RAT_PIT_FF=0.1, ATC_RAT_PIT_FLTT=20.0, ATC_RAT_PIT_FLTE=0.0, ATC_RAT_PIT_D=0.0)
    rc = ardupilot.RateController(p, DT)
    rc.step([0.0] * 3, [0.0] * 3)  # AC_PID's first call after a reset initialises its filters
    r, n = 0.3, 6
    u = np.array([rc.step([r, r, 0.0], [0.0] * 3) for _ in range(n)])
    kp, ki = p["ATC_RAT_RLL_P"], p["ATC_RAT_RLL_I"]
    # integrator updated before the output: backward Euler
    np.testing.assert_allclose(u[:, 0], kp * r + ki * r * DT * np.arange(1, n + 1), rtol=1e-14)
    a = DT / (DT + 1 / (2 * math.pi * 20.0))
    t = r * (1 - (1 - a) ** np.arange(1, n + 1))  # target filter
    integ = p["ATC_RAT_PIT_I"] * DT * np.cumsum(t)
    np.testing.assert_allclose(u[:, 1], p["ATC_RAT_PIT_P"] * t + integ + 0.1 * t, rtol=1e-13)


def test_ardupilot_differentiates_the_filtered_error_set_point_included():
    p = _ap(INS_GYRO_FILTER=0.0, ATC_RAT_RLL_FLTT=0.0, ATC_RAT_RLL_FLTE=0.0, ATC_RAT_RLL_FLTD=0.0,
            ATC_RAT_RLL_I=0.0, ATC_RAT_RLL_D=0.01)
    rc = ardupilot.RateController(p, DT)
    rc.step([0.0] * 3, [0.0] * 3)
    u = rc.step([1.0, 0, 0], [0.0] * 3)[0]
    assert u == pytest.approx(p["ATC_RAT_RLL_P"] + 0.01 / DT, rel=1e-14)  # a derivative kick, as documented


def test_ardupilot_imax_and_motor_limit():
    p = _ap(INS_GYRO_FILTER=0.0, ATC_RAT_RLL_I=2.0, ATC_RAT_RLL_IMAX=0.2, ATC_RAT_RLL_FLTE=0.0,
            ATC_RAT_RLL_FLTT=0.0, ATC_RAT_RLL_D=0.0)
    rc = ardupilot.RateController(p, DT)
    for _ in range(300):
        u = rc.step([1.0, 0, 0], [0.0] * 3)
    assert rc.integral[0] == 0.2
    assert u[0] == pytest.approx(p["ATC_RAT_RLL_P"] + 0.2, rel=1e-14)
    rc.reset()
    rc.step([1.0, 0, 0], [0.0] * 3, limit=[True, False, False])
    assert rc.integral[0] == 0.0


@pytest.mark.parametrize("axis", ardupilot.AXES)
@pytest.mark.parametrize("gyro_filter", [True, False])
def test_ardupilot_lti_form_equals_the_stateful_law_below_saturation(axis, gyro_filter):
    p = _ap(ATC_RAT_RLL_FF=0.05, ATC_RAT_PIT_FLTE=10.0, ATC_RAT_YAW_D=0.002)
    rng = np.random.default_rng(3)
    n = 800
    r = np.r_[0.0, 0.05 * np.cumsum(rng.standard_normal(n - 1)) / 10]
    y = np.r_[0.0, 0.02 * rng.standard_normal(n - 1)]
    ax = ardupilot.AXES.index(axis)
    rc = ardupilot.RateController(p, DT, gyro_filter=gyro_filter)
    got = []
    for k in range(n):
        rv, yv = np.zeros(3), np.zeros(3)
        rv[ax], yv[ax] = r[k], y[k]
        got.append(rc.step(rv, yv)[ax])
    want = _lsim(ardupilot.rate_controller_lti(p, axis, DT, gyro_filter=gyro_filter), np.c_[r, y])[:, 0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.max(np.abs(want)))


def test_ardupilot_angle_p_and_rate_limit():
    p = _ap(ATC_RATE_P_MAX=20.0)
    att = ardupilot.AttitudeController(p)
    th = 0.1
    rate = att.update([1, 0, 0, 0], [math.cos(th / 2), 0, math.sin(th / 2), 0])
    assert rate[1] == pytest.approx(math.radians(20.0))  # 0.45 rad/s asked for, 20 deg/s allowed
    rate = att.update([1, 0, 0, 0], [math.cos(th / 2), 0, 0, math.sin(th / 2)])
    assert rate[2] == pytest.approx(p["ATC_ANG_YAW_P"] * th, rel=1e-12)


# ---------------------------------------------------------------- registry, tables and files

@pytest.mark.parametrize("name", sorted(autopilots.AUTOPILOTS))
def test_registry_walk_every_parameter_documented_and_every_law_built(name):
    ap = autopilots.get(name)
    assert ap.NAME == name and ap.TABLE.autopilot == name and ap.FILE_FORMAT in ("qgc", "parm")
    for s in ap.TABLE:
        assert s.unit and s.description and s.source, s.name
        assert s.in_range(s.default), s.name
        assert len(s.name) <= 16, s.name  # a MAVLink parameter id
    defaults = ap.TABLE.defaults()
    for axis in ap.AXES:
        assert set(ap.axis_names(axis).values()) <= set(defaults)
        C = ap.rate_controller_lti(defaults, axis, 1 / ap.loop_hz(defaults))
        assert C.input_labels == ["rate_sp", "rate"] and C.output_labels == ["torque"]
        poles = np.abs(np.linalg.eigvals(C.A))
        assert np.all(poles <= 1 + 1e-12)  # stable filters, one integrator on the unit circle
        K = ap.attitude_controller_lti(defaults, axis, C.dt)
        assert K.input_labels == ["angle_sp", "angle"] and K.output_labels == ["rate_sp"]
    ap.RateController(defaults, 1 / ap.loop_hz(defaults)).step([0.0] * 3, [0.0] * 3)
    ap.AttitudeController(defaults).update([1, 0, 0, 0], [1, 0, 0, 0])


def test_unknown_autopilot_lists_the_registered_ones():
    with pytest.raises(UnknownNameError, match="ardupilot, px4"):
        autopilots.get("betaflight")


@pytest.mark.parametrize("name, suffix", [("px4", ".params"), ("ardupilot", ".parm")])
def test_parameter_file_round_trip_only_the_tuned_names_and_the_header(tmp_path, name, suffix):
    ap = autopilots.get(name)
    axis = ap.axis_names("pitch")
    tuned = {axis["P"]: 0.123456789, axis["I"]: 0.2345, axis["D"]: 0.0031}
    path = tmp_path / f"tuned{suffix}"
    autopilots.write_params(name, path, tuned, "tuned: pitch rate P, I, D\ngoals: disk margin >= 0.5")
    text = path.read_text()
    assert text.startswith("# tuned: pitch rate P, I, D\n# goals: disk margin >= 0.5\n")
    assert autopilots.read_params(path) == tuned
    all_defaults = ap.TABLE.defaults()
    autopilots.write_params(name, path, all_defaults, "defaults")
    assert autopilots.read_params(path) == all_defaults


def test_qgc_params_file_as_qgroundcontrol_writes_it(tmp_path):
    path = tmp_path / "vehicle.params"
    path.write_text("# Onboard parameters for Vehicle 1\n#\n# Stack: PX4 Pro\n#\n"
                    "# Vehicle-Id Component-Id Name Value Type\n"
                    "1\t1\tIMU_GYRO_RATEMAX\t400\t6\n1\t1\tMC_ROLLRATE_P\t0.150000005960464478\t9\n")
    got = autopilots.read_params(path)
    assert got == {"IMU_GYRO_RATEMAX": 400.0, "MC_ROLLRATE_P": 0.150000005960464478}
    other = tmp_path / "two_components.params"
    other.write_text(path.read_text() + "1\t154\tMC_ROLLRATE_P\t0.3\t9\n")
    assert autopilots.read_params(other)["MC_ROLLRATE_P"] == 0.150000005960464478  # the autopilot's, listed first
    other.write_text(path.read_text() + "1\t1\tMC_ROLLRATE_P\t0.3\t9\n")
    with pytest.raises(ConfigError, match="line 8: given twice"):
        autopilots.read_params(other)
    assert "\tIMU_GYRO_RATEMAX\t400\t6\n" in (autopilots.write_params("px4", tmp_path / "o.params", got, "x")
                                              .read_text())


def test_mission_planner_parm_and_ardupilot_param_files_read(tmp_path):
    (tmp_path / "a.parm").write_text("#NOTE: 26/11/2026\nATC_RAT_RLL_P,0.135\nATC_RAT_RLL_I,0.135\n")
    (tmp_path / "b.param").write_text("ATC_RAT_RLL_P    0.135\nATC_RAT_RLL_I 0.135\n")
    want = {"ATC_RAT_RLL_P": 0.135, "ATC_RAT_RLL_I": 0.135}
    assert autopilots.read_params(tmp_path / "a.parm") == want
    assert autopilots.read_params(tmp_path / "b.param") == want


@pytest.mark.parametrize("text, match", [
    ("ATC_RAT_RLL_P,0.1,7\n", "line 1: a Mission Planner parameter row"),
    ("ATC_RAT_RLL_P,abc\n", "not a number"),
    ("ATC_RAT_RLL_P,nan\n", "not finite"),
    ("atc_rat_rll_p,0.1\n", "not a parameter name"),
    ("ATC_RAT_RLL_P,0.1\nATC_RAT_RLL_P,0.2\n", "given twice"),
])
def test_bad_parameter_files_name_file_line_and_field(tmp_path, text, match):
    path = tmp_path / "bad.parm"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as ei:
        autopilots.read_params(path)
    assert str(path) in str(ei.value)


def test_writing_refuses_values_outside_the_documented_range_and_unknown_names(tmp_path):
    path = tmp_path / "t.params"
    with pytest.raises(ConfigError, match=r"0.01 <= MC_ROLLRATE_P <= 0.5 .*mc_rate_control_params.yaml.*got 0.7"):
        autopilots.write_params("px4", path, {"MC_ROLLRATE_P": 0.7}, "x")
    with pytest.raises(ConfigError, match="3 <= ATC_ANG_RLL_P <= 12"):
        autopilots.write_params("ardupilot", tmp_path / "t.parm", {"ATC_ANG_RLL_P": 28.5}, "x")
    with pytest.raises(ConfigError, match="MC_ROLLRATE_Q"):
        autopilots.write_params("px4", path, {"MC_ROLLRATE_Q": 0.1}, "x")
    with pytest.raises(ConfigError, match="whole number"):
        autopilots.write_params("px4", path, {"IMU_GYRO_RATEMAX": 400.5}, "x")
    assert not path.exists()


def test_a_controller_from_a_log_missing_a_parameter_is_refused():
    log_params = {"MC_ROLLRATE_P": 0.2}
    with pytest.raises(DataError, match="FLIGHT.ulg: px4 parameters missing for the controller: MC_ROLLRATE_I"):
        px4.TABLE.complete(log_params, source="FLIGHT.ulg")
    full = px4.TABLE.complete(log_params, fill_defaults=True)
    assert full["MC_ROLLRATE_P"] == 0.2 and full["MC_ROLLRATE_I"] == px4.TABLE["MC_ROLLRATE_I"].default


@pytest.mark.parametrize("name", sorted(autopilots.AUTOPILOTS))
@pytest.mark.parametrize("axis", ["roll", "yaw"])
def test_fixed_structure_lti_is_affine_in_the_gains_and_equals_the_minimal_form(name, axis):
    ap = autopilots.get(name)
    n = ap.axis_names(axis)
    base = ap.TABLE.defaults()
    if name == "px4":
        base["IMU_DGYRO_CUTOFF"] = 30.0
    else:
        base[n["FLTD"]] = 15.0
    g1 = dict(base, **{n["P"]: 0.1, n["I"]: 0.0, n["D"]: 0.0, n["FF"]: 0.0})
    g2 = dict(base, **{n["P"]: 0.3, n["I"]: 0.4, n["D"]: 0.004, n["FF"]: 0.2})
    mid = {k: 0.5 * (g1[k] + g2[k]) for k in g1}
    S1, S2, Sm = (ap.rate_controller_lti(g, axis, DT, fixed_structure=True) for g in (g1, g2, mid))
    assert S1.nstates == S2.nstates == Sm.nstates
    for M in ("A", "B", "C", "D"):
        np.testing.assert_allclose(getattr(Sm, M), 0.5 * (getattr(S1, M) + getattr(S2, M)), rtol=0, atol=1e-12)
    # the kept states of a zero gain change nothing in the response
    u = np.random.default_rng(5).standard_normal((200, 2))
    np.testing.assert_allclose(_lsim(S1, u), _lsim(ap.rate_controller_lti(g1, axis, DT), u), atol=1e-12)


# ---------------------------------------------------------------- PX4 autotune's rule

def test_px4_gmvc_rule_reproduces_px4s_own_unit_test():
    """src/lib/pid_design/pid_design_test.cpp: kc 0.129, ki 11.911 / 5, kd 0.0463 (tolerances as PX4's)."""
    from rotorlab.autopilots import px4_autotune

    kc, ki, kd = px4_autotune.gmvc_pid((0.0098, -0.162, 0.147), (1.0, -1.814, 0.822), 0.004, 0.1, 1.0, 0.5)
    assert abs(kc - 0.129) < 0.001 and abs(ki - 11.911 / 5) < 0.001 and abs(kd - 0.0463) < 0.0001
    assert px4_autotune.gmvc_pid((0.0, 0.0, 0.0), (1.0, -1.5, 0.7), 0.01, 0.1, 1.0, 0.0) == (0.0, 0.0, 0.0)


def test_px4_autotune_from_a_fitted_arx_model_by_hand():
    from rotorlab.autopilots import px4_autotune

    num, den, dt = np.array([0.02, 0.01, 0.0]), np.array([1.0, -1.6, 0.64]), 0.005
    rng = np.random.default_rng(11)
    u = np.sign(np.sin(np.arange(4000) * dt * 2 * np.pi * 1.3)) + 0.3 * rng.standard_normal(4000)
    y = sig.lfilter(np.r_[0.0, num], den, u)  # A(q^-1) y = q^-1 B(q^-1) u
    got_num, got_den = px4_autotune.arx221_fit(u, y)
    np.testing.assert_allclose(got_num, num, atol=1e-10)
    np.testing.assert_allclose(got_den, den, atol=1e-10)
    gains = px4_autotune.autotune_gains({"pitch": (num, den)}, dt)
    kc, ki, kd = px4_autotune.gmvc_pid(num, den, dt, 0.14, 0.0, 0.7)
    assert gains == pytest.approx({"MC_PITCHRATE_P": kc, "MC_PITCHRATE_K": 1.0, "MC_PITCHRATE_I": kc * ki,
                                   "MC_PITCHRATE_D": kc * kd,
                                   "MC_PITCH_P": min(max(1 / (math.radians(60) * kc), 2.0), 6.5)}, rel=1e-12)
    px4.TABLE.check(gains)  # what autotune saves is in the documented ranges
    with pytest.raises(DataError, match="PX4 autotune would reject the gains .*pitch kc = -"):
        px4_autotune.autotune_gains({"pitch": (-100 * num, den)}, dt)  # a reversed input gives kc < 0
    with pytest.raises(DataError, match="excite"):
        px4_autotune.arx221_fit(np.zeros(100), np.zeros(100))


def test_px4_gmvc_critically_damped_design_by_hand():
    """With damping index 0 (the module's call) the GMVC target is the double pole ``r = exp(-2 dt / sigma)``:
    ``p1 = -2 r``, ``p2 = r^2``. For ``A = 1 - 1.6 q^-1 + 0.64 q^-2``, ``B = 0.02 + 0.01 q^-1``, dt 5 ms,
    sigma 0.14 s, detune 0.7, worked by hand: e1 = 0.737874, f0 = 0.545350, f1 = -1.012837, f2 = 0.472239,
    nu = 0.752136, so kc = 0.090887, ki = 0.545350 ... / 5 = 2.78079, kd = 0.0345409, attitude P 6.5 (clipped)."""
    from rotorlab.autopilots import px4_autotune

    r = math.exp(-2 * 0.005 / 0.14)
    e1 = 1.6 - 2 * r + 1
    f0, f1, f2 = 1.6 * e1 - 1.6 - 0.64 + e1 + r * r, -1.6 * e1 - 0.64 * e1 + 0.64, 0.64 * e1
    assert (e1, f0, f1, f2) == pytest.approx((0.737874, 0.545350, -1.012837, 0.472239), abs=2e-6)
    kc, ki, kd, att_p = px4_autotune.design((0.02, 0.01, 0.0), (1.0, -1.6, 0.64), 0.005, 0.14)
    assert kc == pytest.approx(0.068359 / 0.752136, rel=2e-5)
    assert ki == pytest.approx(-(f0 + f1 + f2) / (0.005 * (f1 + 2 * f2)) / 5, rel=1e-9)
    assert (ki, kd) == pytest.approx((2.78079, 0.0345409), rel=2e-5)
    assert att_p == 6.5  # 1 / (60 deg x 0.0909) = 10.5, clipped to 6.5


def test_px4_autotune_signal_is_the_washed_out_step_sequence():
    """getIdentificationSignal: steps of 0 and the amplitude lasting 6, 10, 9, ..., 2 ticks, then 6, 5, 4, 3, 2
    over and over (``_max_steps`` counts down to 1 and restarts at 5), minus their
    first-order wash-out (alpha 1/3 per tick): the value is positive while the step is up, negative while down,
    and decays by 2/3 per tick."""
    from rotorlab.autopilots import px4_autotune

    s = px4_autotune.StepSignal(0.7)
    v = np.array([s.next() for _ in range(150)])
    runs = [len(list(g)) for _, g in itertools.groupby(v > 0)]
    assert runs[:21] == [6, 10, 9, 8, 7, 6, 5, 4, 3, 2, 6, 5, 4, 3, 2, 6, 5, 4, 3, 2, 6]
    assert v[0] == pytest.approx(0.7) and v[1] == pytest.approx(0.7 * 2 / 3) and v[5] == pytest.approx(0.7 * (2 / 3) ** 5)
    assert v[6] == pytest.approx(-0.7 * (1 - (2 / 3) ** 6))


def test_px4_system_identification_is_the_regularised_forgetting_least_squares():
    """The recursion equals its closed form at every step: theta_N minimises ``sum lambda^(N-k) e_k^2 +
    lambda^N theta' P0^-1 theta`` (P0 = 1e4 I, lambda = 1 - dt/60) over the band-passed samples, the regressor
    ``[-y[k-1], -y[k-2], u[k-1], u[k-2], u[k-3]]`` starting once it holds no initial zeros; the high-pass is
    ``h[k] = a (h[k-1] + x[k] - x[k-1])``, ``a = fs / (fs + pi)``, from the first sample (the low-pass is off
    at a cutoff at Nyquist). Data: noisy, not from an ARX model, so every weight matters."""
    from rotorlab.autopilots import px4_autotune

    dt = 0.005
    rng = np.random.default_rng(3)
    u, y = rng.standard_normal(400), np.cumsum(rng.standard_normal(400)) * 0.1
    sid = px4_autotune.SystemIdentification(dt, 100.0, dt)  # 100 Hz at 200 Hz: low-pass off
    for a, b in zip(u, y):
        sid.update_filters(a, b)
        sid.update()
    alpha = (1 / dt) / (1 / dt + math.pi)
    hu, hy = np.zeros(400), np.zeros(400)
    for k in range(1, 400):
        hu[k] = alpha * (hu[k - 1] + u[k] - u[k - 1])
        hy[k] = alpha * (hy[k - 1] + y[k] - y[k - 1])
    lam = 1 - dt / 60
    ks = np.arange(5, 400)  # the recursion starts at the sixth sample
    Phi = np.column_stack([-hy[ks - 1], -hy[ks - 2], hu[ks - 1], hu[ks - 2], hu[ks - 3]])
    w = lam ** (ks[-1] - ks)
    n = len(ks)
    M = Phi.T @ (w[:, None] * Phi) + lam**n * np.eye(5) / 1e4
    want = np.linalg.solve(M, Phi.T @ (w * hy[ks]))
    np.testing.assert_allclose(sid.theta, want, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(sid.variances, np.diag(np.linalg.inv(M)), rtol=1e-7)


def test_px4_autotune_identifies_an_arx_loop_and_keeps_the_design_at_convergence():
    """A P-controlled plant that is exactly the module's ARX model at the loop rate (200 Hz, 100 Hz gyro cutoff:
    model period = loop period, low-pass off): the band-pass keeps the ARX relation, the recursion recovers the
    model, and the module moves on at its first publishing tick after 5 s (every 21 loop periods, 105 ms:
    5.04 s) with the gains designed from that model; a reversed input is refused with the set."""
    from rotorlab.autopilots import px4_autotune

    num, den = np.array([0.02, 0.01, 0.005]), np.array([1.0, -1.6, 0.64])
    st = {"u": [0.0] * 3, "y": [0.0] * 2}

    def loop(r):
        yk = -den[1] * st["y"][-1] - den[2] * st["y"][-2] + num @ st["u"][::-1][:3]
        uk = 2.0 * (r - yk)
        st["y"] = [st["y"][-1], yk]
        st["u"] = [st["u"][1], st["u"][2], uk]
        return uk, yk

    res = px4_autotune.identify_axis(loop, "roll", 0.005, 100.0, 1 / 2.0)
    assert res.model_dt_s == 0.005 and res.time_s == pytest.approx(5.04)
    # the washed-out steps held for 105 ms excite the model's response, not each coefficient: the fit is the
    # plant within 1 % and 0.6 deg up to half the Nyquist frequency
    z = np.exp(2j * np.pi * np.geomspace(0.1, 50.0, 30) * 0.005)
    got, want = (np.polyval(b[::-1], 1 / z) / z / np.polyval(a[::-1], 1 / z) for b, a in ((res.num, res.den), (num, den)))
    assert np.max(np.abs(np.abs(got / want) - 1)) < 0.01
    assert np.max(np.abs(np.angle(got / want, deg=True))) < 0.6
    # the gains kept are those designed from the model one publishing tick earlier: the same within 0.2 %
    assert (res.kc, res.ki, res.kd, res.att_p) == pytest.approx(
        px4_autotune.design(res.num, res.den, 0.005, 0.14), rel=2e-3)
    g = px4_autotune.autotune_params({"roll": res})
    assert g["MC_ROLLRATE_I"] == pytest.approx(res.kc * res.ki) and g["MC_ROLLRATE_D"] == pytest.approx(res.kc * res.kd)
    bad = px4_autotune.AxisResult("yaw", num, den, 0.005, -0.1, 1.0, 0.0, 6.5, 5.0)
    with pytest.raises(DataError, match="every axis: yaw kc = -0.1"):
        px4_autotune.autotune_params({"roll": res, "yaw": bad})
    with pytest.raises(ValueError, match="MC_AT_RISE_TIME"):
        px4_autotune.identify_axis(loop, "roll", 0.005, 100.0, 1.0, rise_time_s=0.6)


def test_px4_arx_rls_reproduces_px4s_own_unit_test():
    """src/lib/system_identification/arx_rls_test.cpp, test221: five zero samples, then (1, 2), (3, 4), (5, 6),
    (7, 8) give -1.81, 1.06, 0.38, -0.27, 0.26 (PX4's tolerance 1e-2); a reset starts from zero and 1e4."""
    from rotorlab.autopilots import px4_autotune

    r = px4_autotune.ArxRls()
    for u, y in [(0.0, 0.0)] * 5 + [(1.0, 2.0), (3.0, 4.0), (5.0, 6.0), (7.0, 8.0)]:
        r.update(u, y)
    assert np.max(np.abs(r.theta - [-1.81, 1.06, 0.38, -0.27, 0.26])) < 1e-2
    fresh = px4_autotune.ArxRls()
    assert np.all(fresh.variances == 1e4) and not fresh.theta.any()


def test_px4_system_identification_reproduces_px4s_own_unit_tests():
    """src/lib/system_identification/system_identification_test.cpp: ``basicTest`` (800 Hz, high-pass 0.05 Hz,
    low-pass 30 Hz, forgetting 80 s; five zero samples, then (0, 1), (2, 3), ..., (8, 9): -3.96, 1.30, -2.28,
    -0.33, 0.369 within 1e-2) and ``simulatedModelTest`` (200 Hz, a square input switching every 30 samples
    with biases through a known ARX model for 2 s: the model within 1e-3)."""
    from rotorlab.autopilots import px4_autotune

    sid = px4_autotune.SystemIdentification(1 / 800, 30.0, 1 / 800, hpf_hz=0.05, forget_tau_s=80.0)
    for u, y in [(0.0, 0.0)] * 5 + [(float(i), float(i + 1)) for i in range(0, 10, 2)]:
        sid.update_filters(u, y)
        sid.update()
    assert np.max(np.abs(sid.theta - [-3.96, 1.30, -2.28, -0.33, 0.369])) < 1e-2

    a1, a2, b0, b1, b2 = -1.77, 0.77, 0.3812, -0.25, 0.2
    sid = px4_autotune.SystemIdentification(1 / 200, 30.0, 1 / 200, hpf_hz=0.05, forget_tau_s=60.0)
    d1 = d2 = u = y = 0.0
    for i in range(400):
        if sid.initialised and i % 30 == 0:
            u = -1.0 if u > 0 else 1.0
        sid.update_filters(u - 0.1, y + 0.2)  # the new input and the previous output, both biased
        sid.update()
        d0 = u - d1 * a1 - d2 * a2  # the model, direct form II
        y = d0 * b0 + d1 * b1 + d2 * b2
        d1, d2 = d0, d1
    assert np.max(np.abs(sid.theta - [a1, a2, b0, b1, b2])) < 1e-3
