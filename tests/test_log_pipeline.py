"""``rotorlab pipeline --log``: from a flight log the project writes itself (tests/flightlog_sim.py: known plant and
controller) to a report and a parameter file, through the stage machinery (resume, cache), and its refusals.

The simulated flight's plants share one motor pole, as a multirotor's axes do (flightlog_sim's default gives yaw a
slower pole than roll and pitch, which an X-frame twin, whose rotors all drive every axis, cannot have)."""

import json
import re

import flightlog_sim as fs
import numpy as np
import pytest

from rotorlab.cli import main
from rotorlab.ident.flightlogs.writers import write_dataflash, write_ulog

PLANTS = {"roll": (400.0, 0.03), "pitch": (350.0, 0.03), "yaw": (60.0, 0.03)}


@pytest.fixture(scope="module")
def flight():
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fs, "PLANTS", PLANTS)
        yield fs.fly(seed=3, excite_s=10.0)


@pytest.fixture(scope="module")
def px4_run(flight, tmp_path_factory):
    """The tiny level on the simulated PX4 flight, serially (the numbers are the executor's anyway)."""
    folder = tmp_path_factory.mktemp("logpipe")
    log = write_ulog(folder / "flight.ulg", fs.px4_topics(flight), fs.px4_params(), {"ver_sw_release": 0x010E0000})
    out = folder / "run"
    argv = ["pipeline", "--log", str(log), "--tiny", "--out", str(out), "--executor", "serial", "--no-progress"]
    assert main(argv) == 0
    return log, out, argv


def test_log_pipeline_writes_report_and_parameter_file(px4_run, capsys):
    from rotorlab import autopilots

    _, out, _ = px4_run
    report = (out / "report" / "report.md").read_text()
    # the pilot's part comes first: the verdict and the per-axis table of the log's against the tuned set
    assert report.index("## Before you fly") < report.index("**Verdict.**") < report.index("## Evidence")
    for axis in fs.AXES:
        assert f"| {axis} | log |" in report and f"| {axis} | tuned |" in report
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["verdict"] and summary["files"][0] == "report.md"
    # the parameter file: PX4's format, the tuned gains of every axis with K = 1, within the documented ranges
    params = autopilots.read_params(out / "report" / summary["tune"]["params_file"])
    autopilots.px4.TABLE.check(params)
    for axis in fs.AXES:
        names = autopilots.px4.axis_names(axis)
        assert params[names["K"]] == 1.0 and params[names["P"]] > 0 and names["ANG_P"] in params
    assert params == pytest.approx(summary["tune"]["tuned"])


def test_calibrated_twin_matches_the_true_plant(px4_run):
    """Ground truth: the simulated plant K / (s (tau s + 1)) with one loop period of delay and the held torque
    (half a period more). The calibrated twin's response (normalised torque -> rad/s) is within 1 dB and 6 deg of
    it over the calibration band, every axis: the twin matches the identified plants to 0.4 dB and 2 deg, and the
    identification from 10 s of excitation per axis puts yaw's delay 2 ms short (5.6 deg at 30 rad/s)."""
    from rotorlab.pipeline.stages.log_calibrate import _SCALE
    from rotorlab.vehicles import load_vehicle
    from rotorlab.vehicles.fit_axes import twin_response

    _, out, _ = px4_run
    v = load_vehicle(str(out / "report" / "vehicle.toml"))
    w = np.logspace(0.0, np.log10(30.0), 12)
    twin = twin_response(v, list(fs.AXES), w)
    s = 1j * w
    for axis, (K, tau) in PLANTS.items():
        truth = K / (s * (tau * s + 1)) * np.exp(-s * (fs.DELAY_SAMPLES + 0.5) / fs.LOOP_HZ)
        r = twin[axis] * _SCALE / truth
        assert np.max(np.abs(20 * np.log10(np.abs(r)))) < 1.0, axis
        assert np.max(np.abs(np.degrees(np.angle(r)))) < 6.0, axis


def test_twin_predicts_the_held_out_flight(px4_run):
    """The calibrated twin closed with the log's own controller predicts the held-out rate (set-point -> rate) about
    as well as the closed-loop model fitted to the same data (within 1 VAF point: the twin is physical, the fit is
    free), and well in absolute terms."""
    _, out, _ = px4_run
    pred = json.loads((out / "stages" / "calibrate" / "stage.json").read_text())["result"]["prediction"]
    assert set(pred) == set(fs.AXES)
    for axis, p in pred.items():
        assert p["twin_vaf_pct"] > 95.0, axis
        assert p["twin_vaf_pct"] >= p["closed_loop_vaf_pct"] - 1.0, axis


def test_validation_flies_both_sets_in_the_twin(px4_run):
    _, out, _ = px4_run
    val = json.loads((out / "stages" / "validate" / "stage.json").read_text())["result"]
    assert val["sets"] == ["log", "tuned"] and not val["twin_skipped"]
    for key in ("gust-pitch", "gust-roll", "hover"):
        assert set(val["twin"][key]) == {"log", "tuned"}
        assert (out / "stages" / "validate" / "logs" / f"{key}__tuned.parquet").is_file()
    for axis in fs.AXES:
        for name in ("log", "tuned"):
            lin = val["linear"][axis][name]
            assert lin["rate"]["stable"] and lin["attitude"]["stable"], (axis, name)


def test_rerun_is_cached_and_resumes(px4_run, capsys):
    log, out, argv = px4_run
    capsys.readouterr()
    assert main(argv) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("[")]
    assert len(lines) == 5 and all(" cached " in ln for ln in lines)
    # a stage removed is recomputed, and only what depends on it
    import shutil

    shutil.rmtree(out / "report")
    assert main(argv) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("[")]
    assert [ln.split()[1] for ln in lines if "done in" in ln] == ["report"]


def test_ardupilot_log_runs_to_a_parm_file(flight, tmp_path):
    from rotorlab import autopilots

    # the log carries the whole parameter table, as ArduCopter logs do (the plant through the controller needs it)
    params = {**autopilots.ardupilot.TABLE.defaults(), "ATC_RAT_RLL_P": 0.15}
    log = write_dataflash(tmp_path / "flight.bin", fs.dataflash_messages(flight), params)
    out = tmp_path / "run"
    assert main(["pipeline", "--log", str(log), "--tiny", "--out", str(out), "--executor", "serial",
                 "--no-progress"]) == 0
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["identify"]["autopilot"] == "ardupilot"
    f = out / "report" / summary["tune"]["params_file"]
    assert f.suffix == ".parm"
    autopilots.ardupilot.TABLE.check(autopilots.read_params(f))


@pytest.mark.parametrize("case, expect", [
    (["--log", "{tmp}/missing.ulg"], "missing.ulg: no such file"),
    (["--log", "{tmp}/flight.txt"], "unknown flight-log format"),
    (["--log", "{tmp}/flight.ulg"], "flight.ulg"),
    (["--log", "{tmp}/flight.ulg", "--vehicle", "{tmp}/bad.toml"], "mass_kg"),
    (["--log", "{tmp}/flight.ulg", "--n-boot", "10"], "--n-boot/--n-mc"),
    (["--autopilot", "px4"], "--autopilot: expected it with --log"),
])
def test_bad_input_exits_2_naming_what(case, expect, tmp_path, capsys):
    from rotorlab.vehicles import vehicle_path

    (tmp_path / "flight.txt").write_text("x")
    (tmp_path / "flight.ulg").write_bytes(b"not a ulog")
    text = vehicle_path("x500").read_text()
    (tmp_path / "bad.toml").write_text(re.sub(r"(?m)^mass_kg = .*$", "mass_kg = -1.0", text, count=1))
    argv = ["pipeline", *[a.format(tmp=tmp_path) for a in case], "--out", str(tmp_path / "run"), "--tiny",
            "--executor", "serial", "--no-progress"]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and expect in err and "Traceback" not in err, err


def test_every_log_stage_module_is_registered():
    import pkgutil

    from rotorlab.pipeline import stages

    mods = {m.name for m in pkgutil.iter_modules(stages.__path__) if m.name.startswith("log_")}
    assert {getattr(stages, m).STAGE.name for m in mods} == set(stages.LOG_REGISTRY)
    # every upstream a stage names comes before it
    order = list(stages.LOG_REGISTRY)
    for i, st in enumerate(stages.LOG_REGISTRY.values()):
        assert all(order.index(u) < i for u in st.upstream)


def _case(disk, dist, noise=(1.0, 1.0), stable=True):
    """Crafted stage results of one axis, roll: (log, tuned) disk margins, disturbance peaks (rad), noise gains."""
    an = {s: {"roll": {"stable": stable or s == "log", "disk_alpha": d, "noise_gain": n}}
          for s, d, n in zip(("log", "tuned"), disk, noise)}
    lin = {"roll": {s: {"rate": {"stable": True}, "attitude": {"stable": True},
                        "disturbance": {"stable": True, "peak_rad": p}} for s, p in zip(("log", "tuned"), dist)}}
    tune = {"axes": ["roll"], "analysis": an, "params_file": "tuned.params", "failed": [], "autopilot": "px4"}
    cal = {"prediction": {"roll": {"twin_vaf_pct": 98.0, "closed_loop_vaf_pct": 98.5}}}
    return tune, {"linear": lin, "twin": {}}, cal


def test_verdict_recommends_an_axis_only_when_it_is_no_worse():
    from rotorlab.pipeline.stages.log_report import verdict

    # better disturbance rejection, same margin: fly the tuned file
    lines, worse, rec = verdict(*_case(disk=(0.8, 0.8), dist=(0.1, 0.05)))
    assert rec == ["roll"] and lines[0].startswith("Fly `tuned.params` (roll)") and not worse
    # disturbance peak 10 % worse (beyond the 5 % allowance): keep the log's gains
    lines, worse, rec = verdict(*_case(disk=(0.8, 0.8), dist=(0.1, 0.11)))
    assert rec == [] and lines[0].startswith("Keep the log's parameters") and "disturbance peak" in worse["roll"][0]
    # a lower disk margin refuses too; more gyro noise is only to weigh
    assert verdict(*_case(disk=(0.8, 0.7), dist=(0.1, 0.05)))[2] == []
    lines, worse, rec = verdict(*_case(disk=(0.8, 0.8), dist=(0.1, 0.05), noise=(1.0, 2.0)))
    assert rec == ["roll"] and any("to weigh" in x and "gyro-noise gain 1 -> 2" in x for x in lines)
    # unstable with the tuned gains on the identified plant's analysis: not recommended
    assert verdict(*_case(disk=(0.8, 0.8), dist=(0.1, 0.05), stable=False))[2] == []
    # a twin that predicts the flight far worse than the closed-loop fit does not vouch
    tune, val, cal = _case(disk=(0.8, 0.8), dist=(0.1, 0.05))
    cal["prediction"]["roll"]["twin_vaf_pct"] = 40.0
    assert verdict(tune, val, cal)[0][0].startswith("Not validated on roll")
    # pitch and yaw were not tuned: the verdict says to keep their log gains
    assert any(x.startswith("pitch, yaw: not tuned") for x in verdict(tune, val, cal)[0])


# -- the twin pipeline's --controller ------------------------------------------------------------------------------

def test_twin_pipeline_validation_flies_an_autopilot():
    """The validate stage's task with an autopilot flies its laws (not the cascade) in the same scenario and seed."""
    from rotorlab.gains import load_gains
    from rotorlab.pipeline.models import gains_table
    from rotorlab.pipeline.runner import _controller_setting
    from rotorlab.pipeline.stages.validate import run_validation
    from rotorlab.vehicles import gains_path

    std = gains_table(load_gains(gains_path("tuhh-quad", "standard")))
    base = {"scenario": "gust", "vehicle": "tuhh-quad", "seed": 1, "gains": std, "duration_s": 3.5, "options": {}}
    ap = _controller_setting("px4:defaults")
    assert ap["name"] == "px4:defaults" and ap["params"]["MC_ROLLRATE_P"] == 0.15
    flown = run_validation({**base, "set": ap["name"], "autopilot": ap})
    cascade = run_validation({**base, "set": "standard"})
    assert flown["stopped"] is None and cascade["stopped"] is None
    # the pitch command differs from the cascade's: another law flew on the same gust
    assert not np.allclose(flown["columns"]["u_lon"], cascade["columns"]["u_lon"])


def test_controller_enters_only_the_validate_stage_hash():
    from rotorlab.pipeline import PipelineOptions, settings_for
    from rotorlab.pipeline.runner import _controller_setting, stage_hash

    opts = PipelineOptions(vehicle="tuhh-quad", level="tiny")
    s0 = settings_for("tiny")
    s1 = {**s0, "controller": _controller_setting("px4:defaults")}
    ups = {}
    assert stage_hash("validate", opts, s0, {}, ups) != stage_hash("validate", opts, s1, {}, ups)
    assert stage_hash("identify", opts, s0, {}, ups) == stage_hash("identify", opts, s1, {}, ups)


@pytest.mark.parametrize("case, expect", [
    (["--controller", "px4:{tmp}/missing.params"], "missing.params"),
    (["--controller", "betaflight:x"], "--controller: expected AUTOPILOT:PARAMS"),
    (["--controller", "px4:defaults", "--log", "{tmp}/flight.ulg"], "--controller: expected it without --log"),
])
def test_bad_controller_exits_2(case, expect, tmp_path, capsys):
    (tmp_path / "flight.ulg").write_bytes(b"not a ulog")
    argv = ["pipeline", *[a.format(tmp=tmp_path) for a in case], "--out", str(tmp_path / "run"), "--tiny",
            "--executor", "serial", "--no-progress"]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and expect in err and "Traceback" not in err, err
