"""``rotorlab pipeline --log``: from a flight the twin writes itself to a report and a parameter file, through the
stage machinery (resume, cache), and its refusals.

Issue 29's acceptance set-up: tuhh-quad flies PX4's laws with PX4 autotune's excitation on each axis in turn and
writes the flight as a ULog (:func:`rotorlab.twinlogs.fly_twin_log`); the pipeline starts from a plus-quad file with
tuhh-quad's mass, geometry and rotor but inertia and motor pole 30 % off (:func:`start_file`). Ground truth is
tuhh-quad itself: its per-axis response, and its own parameters flown against the tuned ones."""

import json
import re

import numpy as np
import pytest

from rotorlab.cli import main
from rotorlab.vehicles import VEHICLES_DIR, load_vehicle

AXES = ("roll", "pitch", "yaw")
TRUE_INERTIA = "inertia_kgm2 = [0.0181, 0.0196, 0.0273]"
TRUE_LAG = "lag_s = [0.037088, 0.036892, 0.037088, 0.036892]"


def start_file(folder):
    """tuhh-quad's vehicle file without its rigs, inertia x1.3 / x0.7 / x1.3 and the motor pole x0.7 (lag / 0.7)."""
    text = (VEHICLES_DIR / "tuhh-quad" / "vehicle.toml").read_text().split("[rig.pitch]")[0]
    assert TRUE_INERTIA in text and TRUE_LAG in text
    text = text.replace(TRUE_INERTIA, "inertia_kgm2 = [0.02353, 0.01372, 0.03549]")
    text = text.replace(TRUE_LAG, "lag_s = [0.052983, 0.052703, 0.052983, 0.052703]")
    text = re.sub(r'(?m)^name = "tuhh-quad"', 'name = "tuhh-start"', text, count=1)
    path = folder / "start.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def px4_run(tmp_path_factory):
    """The tiny level on the twin's PX4 flight, serially (the numbers are the executor's anyway)."""
    from rotorlab.twinlogs import fly_twin_log

    folder = tmp_path_factory.mktemp("logpipe")
    log = fly_twin_log(folder / "twin.ulg", "tuhh-quad", autopilot="px4", seed=0)
    out = folder / "run"
    argv = ["pipeline", "--log", str(log), "--vehicle", str(start_file(folder)), "--tiny", "--out", str(out),
            "--executor", "serial", "--no-progress"]
    assert main(argv) == 0
    return log, out, argv


def test_log_pipeline_writes_report_and_parameter_file(px4_run):
    from rotorlab import autopilots

    _, out, _ = px4_run
    report = (out / "report" / "report.md").read_text()
    # the pilot's part comes first: the verdict and the per-axis table of the log's against the tuned set
    assert report.index("## Before you fly") < report.index("**Verdict.**") < report.index("## Evidence")
    # the calibration's evidence: the refinement on the flight and the residual before and after it
    assert "then refined on the flight" in report and "| axis | max dB | max deg | frequency fit | at the start |" in report
    for axis in AXES:
        assert f"| {axis} | log |" in report and f"| {axis} | tuned |" in report
    summary = json.loads((out / "report" / "summary.json").read_text())
    assert summary["verdict"] and summary["files"][0] == "report.md"
    # the parameter file: PX4's format, the tuned gains of every axis with K = 1, within the documented ranges
    params = autopilots.read_params(out / "report" / summary["tune"]["params_file"])
    autopilots.px4.TABLE.check(params)
    for axis in AXES:
        names = autopilots.px4.axis_names(axis)
        assert params[names["K"]] == 1.0 and params[names["P"]] > 0 and names["ANG_P"] in params
    assert params == pytest.approx(summary["tune"]["tuned"])


def _twin_error(out, axis):
    """(max dB, max deg) of the calibrated twin's rate response against tuhh-quad's over 1-30 rad/s."""
    from rotorlab.vehicles.fit_axes import twin_response

    w = np.logspace(0.0, np.log10(30.0), 15)
    r = (twin_response(load_vehicle(str(out / "report" / "vehicle.toml")), [axis], w)[axis]
         / twin_response(load_vehicle("tuhh-quad"), [axis], w)[axis])
    return float(np.max(np.abs(20 * np.log10(np.abs(r))))), float(np.max(np.abs(np.degrees(np.angle(r)))))


@pytest.mark.parametrize("axis", AXES)
def test_calibrated_twin_is_tuhh_quad(px4_run, axis):
    """Issue 29: from 30 % off in inertia and motor pole, the twin calibrated to the log's plants responds as
    tuhh-quad does within 1 dB and 5 deg over 1-30 rad/s (the start is off by about 3-4 dB)."""
    db, deg = _twin_error(px4_run[1], axis)
    assert db < 1.0 and deg < 5.0, (db, deg)


def test_twin_predicts_the_held_out_flight(px4_run):
    """The calibrated twin closed with the log's own controller predicts the held-out rate (set-point -> rate) about
    as well as the closed-loop model fitted to the same data (within 1 VAF point: the twin is physical, the fit is
    free), and well in absolute terms."""
    _, out, _ = px4_run
    pred = json.loads((out / "stages" / "calibrate" / "stage.json").read_text())["result"]["prediction"]
    assert set(pred) == set(AXES)
    for axis, p in pred.items():
        assert p["twin_vaf_pct"] > 95.0, axis
        assert p["twin_vaf_pct"] >= p["closed_loop_vaf_pct"] - 1.0, axis
    # roll and pitch were refined on the flight's identification windows, each pair of rotors on its own axis
    fit = json.loads((out / "stages" / "calibrate" / "stage.json").read_text())["result"]["flight_fit"]
    assert set(fit["ident_vaf_after_pct"]) == {"roll", "pitch"}
    for axis, after in fit["ident_vaf_after_pct"].items():
        assert after >= fit["ident_vaf_before_pct"][axis], axis


def test_tuned_parameters_beat_the_logs_in_the_validation_scenarios(px4_run):
    """Issue 29: the tuned set against the log's own (tuhh-quad's PX4 defaults flown in the log) in every
    validation scenario: per axis on the calibrated twin's linearisation the input-disturbance peak lower and the
    rate and angle steps tracked more closely (the error's integral per unit of step), at a disk margin no
    smaller; in the MuJoCo twin the gusts' peak deviation and IAE and the hover's RMS error lower (the same gusts
    and turbulence for both)."""
    _, out, _ = px4_run
    val = json.loads((out / "stages" / "validate" / "stage.json").read_text())["result"]
    tune = json.loads((out / "stages" / "tune" / "stage.json").read_text())["result"]
    for axis in AXES:
        lin = val["linear"][axis]
        assert lin["tuned"]["disturbance"]["peak_rad"] < lin["log"]["disturbance"]["peak_rad"], axis
        for loop in ("rate", "attitude"):
            assert lin["tuned"][loop]["iae_per_step_s"] < lin["log"][loop]["iae_per_step_s"], (axis, loop)
        assert tune["analysis"]["tuned"][axis]["disk_alpha"] >= tune["analysis"]["log"][axis]["disk_alpha"] - 1e-3
    from rotorlab.pipeline.stages.log_report import twin_headlines

    figures = twin_headlines(val)
    assert {k[0] for k in figures} == {"gust-pitch", "gust-roll", "hover"} and len(figures) == 6
    for key, by_set in figures.items():
        assert by_set["tuned"] < by_set["log"], key


def test_validation_flies_both_sets_in_the_twin(px4_run):
    _, out, _ = px4_run
    val = json.loads((out / "stages" / "validate" / "stage.json").read_text())["result"]
    assert val["sets"] == ["log", "tuned"] and not val["twin_skipped"]
    for key in ("gust-pitch", "gust-roll", "hover"):
        assert set(val["twin"][key]) == {"log", "tuned"}
        assert (out / "stages" / "validate" / "logs" / f"{key}__tuned.parquet").is_file()
    for axis in AXES:
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


def test_ardupilot_log_runs_to_a_parm_file(tmp_path):
    """The twin flying ArduPilot's laws with SYSID's chirp, written as DataFlash, from the shipped x500."""
    from rotorlab import autopilots
    from rotorlab.twinlogs import fly_twin_log

    # SYSID's chirp from 1 Hz at 20 deg/s, as tests/test_twinlogs.py flies it (SID_F_START_HZ, SID_MAGNITUDE)
    log = fly_twin_log(tmp_path / "twin.bin", "tuhh-quad", autopilot="ardupilot", seed=0,
                       options={"sid_f_start_hz": 1.0, "sid_magnitude_dps": 20.0})
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
