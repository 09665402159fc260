"""What a held-out score means: the held-out windows carry their excitation figures, a run whose held-out part
is not excited says so (its VAF scores noise, not the model), a rate set-point that is the angle loop's output
(computed from the measured attitude, as ArduCopter's STABILIZE logs it) is named with the angle gain recovered,
and the report's time plots keep every extreme of a long high-rate log while plotting a bounded number of
points. Logs made by tests/flightlog_sim.py."""

import json

import numpy as np
import pytest
from flightlog_sim import LOOP_HZ, controller, fly, px4_params, px4_topics, true_plant_d

from rotorlab.ident.flightlogs import read_flight_log
from rotorlab.ident.flightlogs.report import plot_points
from rotorlab.ident.flightlogs.run import ANGLE_LOOP_VAF, identify_flight_log
from rotorlab.ident.flightlogs.windows import MIN_RMS, holdout_excitation, select_windows
from rotorlab.ident.flightlogs.writers import write_ulog
from rotorlab.ident.nugap import nugap


@pytest.fixture(scope="module")
def flight():
    return fly(seed=5, excite_s=8.0)


def _ulog(f, path, autotune=True):
    topics = px4_topics(f)
    if not autotune:
        # without the autotune status the candidate time is the airborne time: its last 40 % holds the yaw
        # excitation only, so the roll axis is identified on its excitation and scored on an unexcited part
        del topics["autotune_attitude_control_status"]
    return write_ulog(path, topics, px4_params())


def test_held_out_windows_carry_the_set_point_rms_in_the_band(flight, tmp_path):
    log = read_flight_log(_ulog(flight, tmp_path / "f.ulg"))
    rec = log.record("roll", ("rate_sp", "rate"))
    split = select_windows(log, rec, "rate_sp", "rate")
    rms, coh = holdout_excitation(split)
    # by hand: the held-out set-point (one window here) with its linear trend removed
    (w,) = split.holdout
    u = rec.data["rate_sp"][(rec.t_s >= w.start_s) & (rec.t_s < w.stop_s)]
    t = np.arange(len(u))
    assert rms == pytest.approx(np.std(u - np.polyval(np.polyfit(t, u, 1), t)), rel=1e-9)
    assert rms > 10 * MIN_RMS["rate_sp"] and coh > 0.8


def test_an_unexcited_held_out_part_is_named(flight, tmp_path):
    quiet = identify_flight_log(_ulog(flight, tmp_path / "q.ulg", autotune=False), tmp_path / "q", ["roll"],
                                controller=None)
    note = [n for n in quiet.notes if n.startswith("roll: the held-out part is not excited")]
    assert note, quiet.notes
    page = (tmp_path / "q" / "report.html").read_text()
    assert "the held-out part is not excited" in page and "rate_sp RMS" in page
    doc = json.loads((tmp_path / "q" / "roll-closed-loop.json").read_text())
    assert doc["settings"]["extra"]["holdout_excitation"]["rms"] < MIN_RMS["rate_sp"]
    excited = identify_flight_log(_ulog(flight, tmp_path / "e.ulg"), tmp_path / "e", ["roll"], controller=None,
                                  report=False)
    assert not [n for n in excited.notes if "held-out part is not excited" in n]
    doc = json.loads((tmp_path / "e" / "roll-closed-loop.json").read_text())
    assert doc["settings"]["extra"]["holdout_excitation"]["rms"] > MIN_RMS["rate_sp"]


def test_plot_points_keep_every_extreme_in_time_order():
    rng = np.random.default_rng(0)
    t = np.arange(600_000) * 1e-3  # ten minutes of a 1 kHz gyro
    x = rng.standard_normal(len(t))
    spikes = rng.choice(len(t), 20, replace=False)
    x[spikes] = 50.0 * np.sign(rng.standard_normal(20))
    tp, xp = plot_points(t, x, 4000)
    assert len(tp) <= 4000 and np.all(np.diff(tp) >= 0)
    # every spike is plotted at its value, at its time or (two of one sign in one run of samples) a run away
    run_s = len(t) / 2000 * 1e-3
    for k in spikes:
        assert np.any((np.abs(tp - t[k]) <= run_s) & (xp == x[k]))
    assert xp.max() == x.max() and xp.min() == x.min()
    short = np.arange(100.0)
    assert plot_points(short, short)[0] is short  # a short series as is


ANGLE_P = 6.5  # 1/s, the angle loop's gain of the angle-mode log


def _angle_mode_ulog(f, path, angle_mode: bool):
    """The flight with the attitude (the roll gyro integrated) and an attitude set-point. ``angle_mode``: the set-point
    is the one from which the angle law ``rate_sp = ANGLE_P (att_sp - att)`` gives the logged rate set-point;
    else level (an acro or autotune flight, where the rate set-point is the pilot's or the autotune's)."""
    topics = px4_topics(f)
    t_us = topics["vehicle_rates_setpoint"]["timestamp"]
    sub = len(f.t_gyro_s) // len(f.t_loop_s)
    att = np.cumsum(f.rate_gyro["roll"][::sub]) / LOOP_HZ
    att_sp = att + f.rate_sp["roll"] / ANGLE_P if angle_mode else np.zeros_like(att)
    z = np.zeros(len(att), np.float32)
    topics["vehicle_attitude"] = {"timestamp": t_us, "roll": att.astype(np.float32), "pitch": z, "yaw": z}
    topics["vehicle_attitude_setpoint"] = {"timestamp": t_us, "roll_body": att_sp.astype(np.float32),
                                           "pitch_body": z, "yaw_body": z}
    return write_ulog(path, topics, {**px4_params(), "MC_ROLL_P": ANGLE_P})


def test_a_rate_set_point_from_the_angle_loop_is_named(flight, tmp_path):
    res = identify_flight_log(_angle_mode_ulog(flight, tmp_path / "a.ulg", True), tmp_path / "a", ["roll"],
                              controller=None, report=False)
    share = res.models["roll"]["closed-loop"].extra["angle_loop"]
    assert share["vaf"] > 99.0 and share["P"] == pytest.approx(ANGLE_P, rel=0.01) and abs(share["F"]) < 0.05
    assert share["P_log"] == ANGLE_P
    # the attitude is the gyro integrated, so the angle law solved for it and differentiated is the rate itself
    assert share["kinematic_vaf"] > 99.0
    assert [n for n in res.notes if n.startswith("roll: the logged rate set-point is the angle loop's output")]
    doc = json.loads((tmp_path / "a" / "roll-closed-loop.json").read_text())
    assert doc["settings"]["extra"]["angle_loop"]["P"] == pytest.approx(ANGLE_P, rel=0.01)
    # the autotune's square wave on the rate set-point is no function of the attitude: no note
    res = identify_flight_log(_angle_mode_ulog(flight, tmp_path / "b.ulg", False), tmp_path / "b", ["roll"],
                              controller=None, report=False)
    level = res.models["roll"]["closed-loop"].extra["angle_loop"]
    assert level["vaf"] < ANGLE_LOOP_VAF
    # a level set-point: the inverted law is the rate set-point's derivative over P, no prediction of the rate
    assert level["kinematic_vaf"] < 50.0
    assert not [n for n in res.notes if "angle loop's output" in n]


def test_the_plant_through_the_angle_and_rate_controllers_is_the_truth(flight, tmp_path):
    """An angle-mode log (the rate set-point the angle law's output): the plant fitted through the angle P and the
    rate PID from the attitude set-point is the simulated plant, and closed again it predicts the held-out rate as
    well as the closed loop identified directly from the attitude set-point."""
    res = identify_flight_log(_angle_mode_ulog(flight, tmp_path / "a.ulg", True), tmp_path / "a", ["roll"],
                              controller=lambda log, axis: controller(axis).lti(), report=False)
    models = res.models["roll"]
    m = models["plant-indirect-angle"]
    assert m.extra["angle_p"] == ANGLE_P
    assert m.extra["params"]["K"] == pytest.approx(400.0, rel=0.05)
    assert nugap(m.model.with_delay(), true_plant_d("roll", m.dt)) < 0.05
    assert m.vaf_holdout > 90.0
    assert abs(m.vaf_holdout - models["closed-loop-angle"].vaf_holdout) < 5.0
    assert (tmp_path / "a" / "roll-plant-indirect-angle.json").exists()


def test_the_log_pipeline_predicts_an_angle_mode_flight_as_the_identification_does(flight, tmp_path, monkeypatch):
    """The log pipeline's check of a twin on an angle-mode axis (twin_holdout_vaf with the angle loop) closes the
    plant the way the identification closed the plant through the angle and rate controllers: given that plant as
    the twin's, it scores the held-out flight as the identification scored it; and the pipeline takes that plant
    (usable_plant) where it agrees with the direct model from the attitude set-point."""
    from rotorlab.ident.flightlogs.plant_structures import fitted_plant
    from rotorlab.pipeline.stages import log_calibrate
    from rotorlab.pipeline.stages.log_identify import usable_plant

    path = _angle_mode_ulog(flight, tmp_path / "a.ulg", True)
    res = identify_flight_log(path, tmp_path / "a", ["roll"], report=False)
    models = res.models["roll"]
    m = models["plant-indirect-angle"]
    monkeypatch.setattr(log_calibrate, "twin_plant_continuous",
                        lambda v, axis: fitted_plant("rate-angle-plant", m.extra["params"]))
    windows = [[w.start_s, w.stop_s] for w in m.split.holdout]
    got = log_calibrate.twin_holdout_vaf(read_flight_log(path), None, "roll", m.dt, windows,
                                         (m.extra["angle_p"], m.extra["ff"]))
    assert got == pytest.approx(m.vaf_holdout, abs=1e-6)
    summary = {k: {"vaf_holdout_pct": x.vaf_holdout, **{e: x.extra[e] for e in ("params", "ci95") if e in x.extra}}
               for k, x in models.items()}
    assert usable_plant(summary, "roll")[0] in ("plant-indirect", "plant-indirect-angle")
    summary.pop("plant-indirect")
    summary["closed-loop"]["vaf_holdout_pct"] = 100.0  # the plant alone would fall below half of it
    summary.pop("plant", None)
    assert usable_plant(summary, "roll")[0] == "plant-indirect-angle"
    assert usable_plant(summary, "yaw")[0] is None


def test_tune_takes_the_plant_ident_wrote_through_the_controller(flight, tmp_path):
    """``rotorlab tune --autopilot px4 --model roll=roll-plant-indirect.json``: the file ``rotorlab ident`` writes
    for the plant through the controller holds its fractional delay as a state at z = 0 (no continuous
    equivalent); tune reads it as its structure's continuous plant with the delay, the one the log pipeline uses,
    and tunes it (it refused the file with 'poles on the non-positive real axis')."""
    from rotorlab.cli import main
    from rotorlab.commands._tune_autopilot import _models
    from rotorlab.ident.flightlogs.plant_structures import fitted_plant

    res = identify_flight_log(_ulog(flight, tmp_path / "f.ulg"), tmp_path / "m", ["roll"], report=False)
    path = tmp_path / "m" / "roll-plant-indirect.json"
    G, delay_s, _ = _models(type("A", (), {"axes": "roll", "model": [f"roll={path}"]})())["roll"]
    want, want_delay = fitted_plant("rate-plant", res.models["roll"]["plant-indirect"].extra["params"])
    assert G.dt == 0 and delay_s == want_delay and np.allclose(np.asarray(G.A), np.asarray(want.A))
    assert main(["tune", "--autopilot", "px4", "--model", f"roll={path}", "--axes", "roll", "--loop-hz", "250",
                 "--out", str(tmp_path / "t.params")]) == 0
