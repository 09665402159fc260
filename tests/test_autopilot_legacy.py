"""Older firmware's parameters mapped onto the current laws (rotorlab.autopilots.legacy), checked against the older
laws written out by hand from their source (ArduCopter 3.4 AC_PID, PX4 2016-2017 mc_att_control)."""

import math

import control as ct
import numpy as np
import pytest

from rotorlab.autopilots import ardupilot, legacy, px4

DT = 1 / 400


def _signals(n=400):
    rng = np.random.default_rng(3)
    return rng.standard_normal(n) * 0.5, rng.standard_normal(n) * 0.5  # rate_sp, rate (rad/s)


def _lti_out(C, r, y):
    return ct.forced_response(C, U=np.vstack([r, y])).outputs.ravel()


def _alpha(f_hz):
    return 1.0 if f_hz <= 0 else DT / (DT + 1 / (2 * math.pi * f_hz))


def _copter34(r, y, P, I, D, filt, yaw):
    """ArduCopter 3.4 rate_target_to_motor_*: set_input_filter_d (roll/pitch) or _all (yaw), then
    get_p() + get_i() + get_d(), the integrator updated before it is used; filters start at zero."""
    a = _alpha(filt)
    inp = der = integ = 0.0
    out = []
    for rk, yk in zip(r, y):
        e = rk - yk
        if yaw:  # set_input_filter_all
            change = a * (e - inp)
            inp += change
            der = change / DT
        else:  # set_input_filter_d
            der += a * ((e - inp) / DT - der)
            inp = e
        integ += inp * I * DT
        out.append(P * inp + integ + D * der)
    return np.array(out)


COPTER34 = {"ATC_RAT_RLL_P": 0.0656, "ATC_RAT_RLL_I": 0.164, "ATC_RAT_RLL_D": 0.0036, "ATC_RAT_RLL_IMAX": 0.222,
            "ATC_RAT_RLL_FILT": 20.0, "ATC_RAT_YAW_P": 0.305, "ATC_RAT_YAW_I": 0.0305, "ATC_RAT_YAW_D": 0.002,
            "ATC_RAT_YAW_IMAX": 0.222, "ATC_RAT_YAW_FILT": 1.1, "INS_GYRO_FILTER": 20.0}


@pytest.mark.parametrize("axis", ["roll", "yaw"])
def test_copter34_filt_maps_to_the_34_law(axis):
    params, mapped = legacy.upgrade("ardupilot", COPTER34)
    tag = {"roll": "RLL", "yaw": "YAW"}[axis]
    assert {m.name for m in mapped} >= {f"ATC_RAT_{tag}_{k}" for k in ("FLTT", "FLTE", "FLTD", "FF")}
    C = ardupilot.rate_controller_lti(params, axis, DT, gyro_filter=False)
    r, y = _signals()
    g = {k: COPTER34[f"ATC_RAT_{tag}_{k}"] for k in ("P", "I", "D", "FILT")}
    want = _copter34(r, y, g["P"], g["I"], g["D"], g["FILT"], yaw=axis == "yaw")
    np.testing.assert_allclose(_lti_out(C, r, y), want, rtol=1e-9, atol=1e-12)


def test_copter34_filt_is_not_the_other_filter():
    # the roll and yaw rules differ: swapping them gives another law (the test above could not pass by accident)
    params, _ = legacy.upgrade("ardupilot", COPTER34)
    C = ardupilot.rate_controller_lti(params, "roll", DT, gyro_filter=False)
    r, y = _signals()
    wrong = _copter34(r, y, 0.0656, 0.164, 0.0036, 20.0, yaw=True)
    assert np.max(np.abs(_lti_out(C, r, y) - wrong)) > 1e-3


def test_values_in_the_log_win():
    p = dict(COPTER34, ATC_RAT_RLL_FLTD=10.0, ATC_RAT_RLL_FF=0.01)
    params, mapped = legacy.upgrade("ardupilot", p)
    assert params["ATC_RAT_RLL_FLTD"] == 10.0 and params["ATC_RAT_RLL_FF"] == 0.01
    assert "ATC_RAT_RLL_FLTD" not in {m.name for m in mapped}
    # a current log (no FILT) gets nothing from the ArduPilot rules
    cur = ardupilot.TABLE.defaults()
    assert legacy.upgrade("ardupilot", cur) == (cur, [])


def _px4_2016(r, y, P, I, D, FF):
    """PX4 2016-2017 control_attitude_rates: P e + int + D (rates_prev - rates) / dt + FF r, int updated after."""
    integ, prev, out = 0.0, 0.0, []
    for rk, yk in zip(r, y):
        e = rk - yk
        out.append(P * e + integ + D * (prev - yk) / DT + FF * rk)
        prev = yk
        integ += I * e * DT
    return np.array(out)


def test_px4_2016_maps_to_the_old_law():
    old = {"MC_ROLLRATE_P": 0.19, "MC_ROLLRATE_I": 0.1, "MC_ROLLRATE_D": 0.0055, "MC_ROLLRATE_FF": 0.02}
    params, mapped = legacy.upgrade("px4", old)
    names = {m.name: m for m in mapped}
    assert names["MC_ROLLRATE_K"].value == 1.0 and names["IMU_DGYRO_CUTOFF"].value == 0.0
    assert px4.loop_hz(params) == 250.0
    C = px4.rate_controller_lti(params, "roll", DT, gyro_filter=False)
    r, y = _signals()
    np.testing.assert_allclose(_lti_out(C, r, y), _px4_2016(r, y, 0.19, 0.1, 0.0055, 0.02), rtol=1e-9, atol=1e-12)


def test_px4_dterm_cutoff_is_renamed_and_tpa_reported():
    old = {"MC_DTERM_CUTOFF": 30.0, "MC_TPA_BREAK_P": 0.3, "MC_TPA_RATE_P": 1.0, "MC_TPA_BREAK_D": 1.0,
           "MC_TPA_RATE_D": 0.0, "MC_ROLLRATE_K": 1.5}
    params, mapped = legacy.upgrade("px4", old)
    assert params["IMU_DGYRO_CUTOFF"] == 30.0 and params["MC_ROLLRATE_K"] == 1.5
    by = {(m.name, m.rule) for m in mapped}
    assert ("IMU_DGYRO_CUTOFF", "renamed") in by and ("MC_TPA_RATE_P", "not modelled") in by
    assert ("MC_TPA_RATE_D", "not modelled") not in by  # breakpoint 1: attenuation off
