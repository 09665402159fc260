"""Faults a user can cause (rotorlab issue 15), one test per measured defect: bad input is exit 2 with a message
naming the file, the field, what was expected and what was got; no traceback reaches the user; nothing already
done is lost.

Items refer to the issue's numbered list. Commands run through ``rotorlab.cli.main`` (capsys) or, where a
signal, a resource limit or a second process is the fault, as subprocesses.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import published_tf

from rotorlab import atomic
from rotorlab.cli import main
from rotorlab.errors import ConfigError
from rotorlab.vehicles import VEHICLES_DIR

P2A2 = VEHICLES_DIR / "anteos-p2a2" / "vehicle.toml"
SPEC = Path(__file__).resolve().parents[1] / "tune" / "specs" / "anteos-p2a2.toml"
ENV = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
CLI = [sys.executable, "-m", "rotorlab.cli"]


def cli(capsys, *argv):
    """Run the CLI in-process; returns (exit status, stdout, stderr)."""
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err + out
    return rc, out, err


def bad(capsys, *argv, says=()):
    """The command must exit 2 with one 'error:' line holding every string of ``says``."""
    rc, out, err = cli(capsys, *argv)
    assert rc == 2, (out, err)
    for s in says:
        assert s in err, (s, err)
    return err


def edited(tmp_path, src: Path, old: str, new: str, name: str = "vehicle.toml") -> Path:
    text = src.read_text()
    assert old in text, old
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return p


def run_rest(vehicle, tmp_path, *extra):
    return ["run", "rest", "--scene", "pitch-rig", "--vehicle", vehicle, "--duration", "0.04",
            "--out", tmp_path / "r", *extra]


# -- item 5: misspelt optional keys are unknown keys, with "did you mean" --------------------------------------
@pytest.mark.parametrize("old,new,field,hint", [
    ("rotor_height_m = 0.10", "rotor_heigth_m = 0.10", "airframe.rotor_heigth_m", "rotor_height_m"),
    ("cp_offset_m = [0.0, 0.0, 0.03]", "cp_ofset_m = [0.0, 0.0, 0.03]", "airframe.cp_ofset_m", "cp_offset_m"),
    ("stop_deg = 30.0\n\n[rig.roll]", "stop_deg = 30.0\nbearing_friction_nm = 0.1\n\n[rig.roll]",
     "rig.pitch.bearing_friction_nm", "bearing_friction_Nm"),
])
def test_misspelt_vehicle_key(tmp_path, capsys, old, new, field, hint):
    v = edited(tmp_path, P2A2, old, new)
    bad(capsys, *run_rest(v, tmp_path), says=(str(v), f"'{field}'", "unknown key", f"did you mean '{hint}'"))


def test_misspelt_spec_key(tmp_path, capsys):
    spec = edited(tmp_path, SPEC, "peak_error = 2.0", "peak_eror = 2.0", "spec.toml")
    model = _model(tmp_path)
    bad(capsys, "tune", "--model", model, "--spec", spec, "--out", tmp_path / "g.toml",
        says=(str(spec), "peak_eror", "did you mean 'peak_error'"))


def test_misspelt_gains_key(tmp_path, capsys):
    g = edited(tmp_path, VEHICLES_DIR / "anteos-p2a2" / "gains" / "standard.toml", "kd", "kdd", "g.toml")
    bad(capsys, *run_rest(P2A2, tmp_path, "--gains", g), says=(str(g), "kdd", "did you mean 'kd'"))


# -- item 6: booleans are booleans --------------------------------------------------------------------------
def test_quoted_boolean_in_spec(tmp_path, capsys):
    spec = edited(tmp_path, SPEC, 'type = "rejection"', 'type = "rejection"\nhard = "false"', "spec.toml")
    bad(capsys, "tune", "--model", _model(tmp_path), "--spec", spec, "--out", tmp_path / "g.toml",
        says=(str(spec), ".hard'", "true or false", "'false'"))


# -- item 7: values that used to reach numpy/MuJoCo as tracebacks ----------------------------------------------
@pytest.mark.parametrize("old,new,field,expected", [
    ("inertia_kgm2 = [0.27, 0.274, 0.50]", "inertia_kgm2 = [nan, 0.274, 0.50]", "airframe.inertia_kgm2", "finite"),
    ("mass_kg = 5.0 ", "mass_kg = 1e-12 ", "airframe.mass_kg", "[0.001, 1000.0]"),
    ("inertia_kgm2 = [0.27, 0.274, 0.50]", "inertia_kgm2 = [0.1, 0.1, 0.5]", "airframe.inertia_kgm2",
     "sum of the other two"),
    ("delay_s = 0.06 ", "delay_s = 100.0 ", "rotor.delay_s", "[0.0, 1.0]"),
])
def test_implausible_vehicle(tmp_path, capsys, old, new, field, expected):
    v = edited(tmp_path, P2A2, old, new)
    bad(capsys, *run_rest(v, tmp_path), says=(str(v), f"'{field}'", expected))


@pytest.mark.parametrize("kind", ["vehicle", "gains"])
@pytest.mark.parametrize("content,says", [
    (bytes(range(256)), "not UTF-8"),
    ("mass_kg = 5.0 # caf\xe9\n".encode("latin-1"), "not UTF-8"),
    (b"[pitch.outer]\nkp = 1.0\x00\n", "NUL"),
])
def test_binary_or_non_utf8_toml(tmp_path, capsys, kind, content, says):
    p = tmp_path / "x.toml"
    p.write_bytes(content)
    args = run_rest(p, tmp_path) if kind == "vehicle" else run_rest(P2A2, tmp_path, "--gains", p)
    bad(capsys, *args, says=(str(p), says))


@pytest.mark.parametrize("old,new,field", [
    ("response_time_s = 0.5", "response_time_s = 0.0", "response_time_s"),
    ("response_time_s = 0.5", "response_time_s = nan", "response_time_s"),
    ("response_time_s = 0.5", "response_time_s = -0.5", "response_time_s"),  # item 10
    ("gain_db = -7.83", "gain_db = nan", "gain_db"),
])
def test_bad_spec_numbers(tmp_path, capsys, old, new, field):
    src = SPEC if old in SPEC.read_text() else SPEC.with_name("anteos-a2minib.toml")
    spec = edited(tmp_path, src, old, new, "spec.toml")
    bad(capsys, "tune", "--model", _model(tmp_path), "--spec", spec, "--out", tmp_path / "g.toml",
        says=(str(spec), field, "expected", "got"))


@pytest.mark.parametrize("scenario,option,says", [
    ("setpoint", "hold_s=fast", ("options.hold_s", "a number", "'fast'")),
    ("setpoint", "t0_s=nan", ("options.t0_s", "finite", "nan")),  # item 10
    ("setpoint", "steps_deg=[nan]", ("options.steps_deg", "finite", "[nan]")),  # item 10
    ("setpoint", "hold_sec=1", ("options.hold_sec", "did you mean 'hold_s'")),
])
def test_bad_scenario_option(tmp_path, capsys, scenario, option, says):
    bad(capsys, "run", scenario, "--option", option, "--duration", "0.04", "--out", tmp_path / "r", says=says)
    assert not (tmp_path / "r" / "log.parquet").exists()


@pytest.mark.parametrize("duration,says", [
    ("inf", "finite duration"), ("nan", "finite duration"), ("1e7", "GiB"),
    ("1e-6", "at least one control step"),  # item 10: was a 0-row log and exit 0
])
def test_duration_checked_before_allocating(tmp_path, capsys, duration, says):
    t0 = time.perf_counter()
    bad(capsys, "run", "rest", "--duration", duration, "--out", tmp_path / "r", says=("'duration'", says, "got"))
    assert time.perf_counter() - t0 < 30  # refused up front, not after allocating 78 GiB


def test_model_delay_bounded(tmp_path, capsys):
    m = tmp_path / "m.json"
    m.write_text(json.dumps({"num": [12.5, 36.4], "den": [1, 5.6, 21.3], "dt": 0, "delay_s": 100}))
    bad(capsys, "tune", "--model", m, "--spec", "anteos-p2a2", "--out", tmp_path / "g.toml",
        says=(str(m), "'delay_s'", "at most 2.0 s", "100"))


def test_log_metadata_not_json(tmp_path, capsys):
    log = _log(tmp_path, meta={b"units": b"{not json", b"rotorlab": b"{}"})
    bad(capsys, "ident", log, "--method", "pi-moesp", "--input", "u", "--output", "y", "--order", "2", "--horizon",
        "5", "--out", tmp_path / "m.json", says=(str(log), "'units'", "expected a JSON object"))


def test_truncated_log(tmp_path, capsys):
    log = _log(tmp_path)
    log.write_bytes(log.read_bytes()[:-40])
    bad(capsys, "ident", log, "--method", "pi-moesp", "--input", "u", "--output", "y", "--out", tmp_path / "m.json",
        says=(str(log), "not a readable Parquet"))


def test_unwritable_out_is_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")  # a file where a folder must go: refused even for root, unlike chmod
    t0 = time.perf_counter()
    bad(capsys, "run", "rest", "--scene", "pitch-rig", "--out", blocker / "run", says=(str(blocker / "run"),
                                                                                      "writable folder"))
    bad(capsys, "pipeline", "--tiny", "--out", blocker / "pl", says=(str(blocker / "pl"), "writable folder"))
    bad(capsys, "pipeline", "--tiny", "--out", blocker, says=(str(blocker), "is a file"))
    assert time.perf_counter() - t0 < 30


# -- item 8: files honour the umask ------------------------------------------------------------------------
@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_atomic_writes_honour_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        p = atomic.write_text(tmp_path / "a.txt", "x")
        with atomic.atomic_path(tmp_path / "b.parquet") as tmp:
            pq.write_table(pa.table({"t": [0.0]}), tmp)
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == mode
    assert stat.S_IMODE((tmp_path / "b.parquet").stat().st_mode) == mode


def test_run_folder_files_are_group_readable(tmp_path):
    r = subprocess.run(["bash", "-c", "umask 022 && exec \"$@\"", "_", *CLI, *map(str, run_rest("anteos-p2a2",
                       tmp_path))], env=ENV, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    for f in ("log.parquet", "run.json"):
        assert stat.S_IMODE((tmp_path / "r" / f).stat().st_mode) == 0o644


# -- item 2: a failed recording write is an error, never a hang or a truncated .rrd ------------------------------
def test_recording_write_fails_cleanly(tmp_path):
    import resource

    rrd = tmp_path / "x.rrd"

    def limit():  # 64 KiB: the log fits, the recording does not
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 << 10, 64 << 10))

    r = subprocess.run([*CLI, "run", "rest", "--scene", "pitch-rig", "--duration", "1", "--out", str(tmp_path / "r"),
                        "--rerun", str(rrd)], env=ENV, capture_output=True, text=True, timeout=120, preexec_fn=limit)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and "cannot write the recording" in r.stderr and str(rrd) in r.stderr
    assert not rrd.exists() and not list(tmp_path.glob(".x.rrd*"))  # nothing truncated at or beside the path


# -- item 3: remote executors fail fast -------------------------------------------------------------------
@pytest.fixture
def silent_server():
    """A TCP server that accepts and never answers (what an HTTP server is to a Dask client)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    conns = []
    stop = threading.Event()

    def serve():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conns.append(srv.accept()[0])
            except OSError:
                pass

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    yield srv.getsockname()[1]
    stop.set()
    th.join()
    for c in conns:
        c.close()
    srv.close()


def test_dask_address_that_is_not_a_scheduler(silent_server, tmp_path, capsys):
    import distributed  # noqa: F401 - its import (seconds on a loaded machine) is not the connect time

    from rotorlab.executor import ExecutorError, get_executor

    t0 = time.perf_counter()
    with pytest.raises(ExecutorError, match="not a Dask scheduler"):
        get_executor(f"dask://127.0.0.1:{silent_server}", timeout_s=2)
    assert time.perf_counter() - t0 < 10
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    bad(capsys, "pipeline", "--tiny", "--executor", f"dask://127.0.0.1:{port}", "--out", tmp_path / "pl",
        says=(f"127.0.0.1:{port}", "no Dask scheduler answered"))
    assert time.perf_counter() - t0 < 60


# -- item 9: tune does not write a gains file that misses its hard goals --------------------------------------
def test_tune_with_failed_hard_goals_leaves_out_alone(tmp_path, capsys):
    # 0.4 s of delay: no PID cascade reaches the 3.5 rad/s crossover band with the required margins
    m = tmp_path / "slow.json"
    m.write_text(json.dumps({"num": [12.5, 36.4], "den": [1, 5.6, 21.3], "dt": 0, "delay_s": 0.4}))
    out = tmp_path / "g.toml"
    rc, text, err = cli(capsys, "tune", "--model", m, "--spec", "anteos-p2a2", "--out", out, "--max-iter", "1")
    assert rc == 1 and "HARD GOALS NOT MET" in text and "not written" in text
    assert not out.exists()
    failed = tmp_path / "g.failed.toml"
    assert failed.read_text().startswith("# FAILED") and "margins at u" in failed.read_text().splitlines()[0]
    from rotorlab.gains import load_gains

    assert load_gains(failed)["pitch"].inner.kp > 0  # still readable, for inspection


# -- item 10: counts, delays and data ranges -------------------------------------------------------------------
@pytest.mark.parametrize("flag,value", [("--starts", "-3"), ("--jobs", "-1"), ("--max-iter", "-5")])
def test_tune_counts(tmp_path, capsys, flag, value):
    with pytest.raises(SystemExit) as exc:
        main(["tune", "--model", "m.json", "--spec", "anteos-p2a2", "--out", str(tmp_path / "g.toml"), flag, value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}: expected a whole number in [1, " in err and f"got {value}" in err


def test_vehicle_delay_not_a_physics_step(tmp_path, capsys):
    v = edited(tmp_path, P2A2, "delay_s = 0.06 ", "delay_s = 0.0605 ")
    bad(capsys, *run_rest(v, tmp_path), says=(str(v), "'rotor.delay_s'", "multiple of the physics step", "0.0605"))


def test_ident_delay_beyond_the_log(tmp_path, capsys):
    log = _log(tmp_path, n=1000)
    t0 = time.perf_counter()
    bad(capsys, "ident", log, "--method", "pi-moesp", "--input", "u", "--output", "y", "--delay", "900",
        "--out", tmp_path / "m.json", says=("--delay 900", "at most 500"))
    assert time.perf_counter() - t0 < 10


def test_ident_log_at_1e300(tmp_path, capsys):
    log = _log(tmp_path, scale=1e300)
    bad(capsys, "ident", log, "--method", "pi-moesp", "--input", "u", "--output", "y", "--order", "2", "--horizon",
        "10", "--out", tmp_path / "m.json", says=(str(log), "expected", "got"))
    assert not (tmp_path / "m.json").exists()


# -- item 11: provenance ---------------------------------------------------------------------------------
def test_run_json_records_a_modified_vehicle(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "myquad"
    folder.mkdir()
    v = edited(folder, P2A2, "mass_kg = 5.0 ", "mass_kg = 5.1 ")
    monkeypatch.chdir(tmp_path)  # a relative vehicle folder
    rc, out, _ = cli(capsys, "run", "rest", "--scene", "pitch-rig", "--vehicle", "myquad", "--duration", "0.04")
    assert rc == 0
    info = json.loads((tmp_path / "runs" / "rest-anteos-p2a2-seed0" / "run.json").read_text())
    src = info["vehicle_source"]
    assert src["path"] == str(v.resolve()) and src["shipped"] is False
    import hashlib

    assert src["sha256"] == hashlib.sha256(v.read_bytes()).hexdigest()
    rc, _, _ = cli(capsys, "run", "rest", "--scene", "pitch-rig", "--duration", "0.04", "--out", tmp_path / "s")
    assert json.loads((tmp_path / "s" / "run.json").read_text())["vehicle_source"]["shipped"] is True


def test_pipeline_default_out_for_a_vehicle_path(tmp_path, capsys, monkeypatch):
    import rotorlab.pipeline as pl

    seen = {}
    monkeypatch.setattr(pl, "run_pipeline", lambda opts: seen.setdefault("opts", opts))
    monkeypatch.chdir(tmp_path)
    v = edited(tmp_path, P2A2, "mass_kg = 5.0 ", "mass_kg = 5.1 ", "x.toml")
    rc, _, _ = cli(capsys, "pipeline", "--tiny", "--vehicle", v)
    assert rc == 0
    assert seen["opts"].out == Path("runs/pipeline-anteos-p2a2-tiny-seed0")
    assert seen["opts"].vehicle == str(v.resolve())


# -- item 12: Ctrl-C and the gym API ---------------------------------------------------------------------
def _interrupt(cmd, wait_for, timeout=120, settle_s=0.5):
    """Start ``cmd`` in its own process group, send SIGINT to the group (a terminal's Ctrl-C) once
    ``wait_for()`` holds, and return the finished process."""
    p = subprocess.Popen(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    t0 = time.perf_counter()
    while not wait_for() and time.perf_counter() - t0 < timeout:
        time.sleep(0.1)
    time.sleep(settle_s)
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=timeout)
    return p.returncode, out, err


def test_ctrl_c_during_run_keeps_the_partial_log(tmp_path):
    out = tmp_path / "r"
    rc, text, err = _interrupt([*CLI, "run", "hover", "--duration", "600", "--out", str(out)],
                               out.exists, settle_s=3.0)  # the folder exists once the inputs are checked
    assert rc == 130, err
    assert "Traceback" not in err
    info = json.loads((out / "run.json").read_text())
    assert info["stopped"] == "interrupted (Ctrl-C)" and 0 < info["rows"] < 30000
    assert pq.read_table(out / "log.parquet").num_rows == info["rows"]


def test_ctrl_c_during_pipeline_prints_no_worker_traceback(tmp_path):
    out = tmp_path / "pl"
    rc, text, err = _interrupt([*CLI, "pipeline", "--tiny", "--workers", "2", "--no-progress", "--out", str(out)],
                               lambda: (out / "stages" / ".experiments.partial").exists())
    assert rc == 130, err
    assert "Traceback" not in err + text and "interrupted" in text + err


def test_gym_step_after_termination_refuses():
    import gymnasium as gym

    env = gym.make("rotorlab/PitchRig-v0", sensor_noise=False)
    env.reset(seed=0)
    for _ in range(2000):
        *_, terminated, truncated, info = env.step(env.action_space.high)
        if terminated or truncated:
            break
    assert terminated, "full command must hit the rig stop"
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(env.action_space.high)
    env.reset(seed=0)
    env.step(env.action_space.low)  # a new episode steps again
    env.close()


@pytest.mark.parametrize("kwargs,field", [
    ({"randomize": ["mass"]}, "randomize"),
    ({"randomize": {"mass": "big"}}, "randomize.mass"),
    ({"randomize": {"delay_s": (10, 20)}}, "randomize.delay_s"),  # item 10
    ({"disturbances": "wind"}, "disturbances"),
    ({"disturbances": [object()]}, "disturbances[0]"),
    ({"episode_s": "long"}, "episode_s"),
])
def test_gym_wrong_typed_kwargs(kwargs, field):
    import re

    from rotorlab.sim.env_rig import RigEnv

    with pytest.raises(ConfigError, match=rf"field '{re.escape(field)}'.*expected.*got"):
        env = RigEnv(**kwargs)
        env.reset(seed=0)


def test_gym_wrong_typed_reset_options():
    from rotorlab.sim.env_rig import RigEnv

    env = RigEnv()
    with pytest.raises(ConfigError, match="field 'options'.*expected a dict"):
        env.reset(options=["randomize"])


# -- item 13: every executor runs tasks on single-threaded BLAS --------------------------------------------
BLAS_THREADS = """
import ctypes
import rotorlab  # first, as the CLI does
import numpy, scipy.linalg  # both bundle an OpenBLAS
paths = sorted({ln.split()[-1] for ln in open("/proc/self/maps") if "openblas" in ln.lower() and ".so" in ln})
for path in paths:
    lib = ctypes.CDLL(path)
    fn = [getattr(lib, n) for n in (
        "scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads", "openblas_get_num_threads64_",
        "openblas_get_num_threads") if hasattr(lib, n)]
    print(path.rsplit("/", 1)[-1], fn[0]() if fn else "?")
"""


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="reads the loaded libraries from /proc")
def test_blas_runs_one_thread_per_process():
    """Dask workers run one BLAS thread; the CLI process and its forked pool workers ran one per core, and the
    threaded sums made dask and local summaries differ by up to 1.6e-10. `import rotorlab` now sets one thread
    (unless the user set the variables), so every executor computes the same bits."""
    env = {k: v for k, v in ENV.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    r = subprocess.run([sys.executable, "-c", BLAS_THREADS], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    rows = [ln.split() for ln in r.stdout.splitlines()]
    assert len(rows) >= 1 and all(n == "1" for _, n in rows), r.stdout


# -- items 1 and 4: the run-folder lock and the verified cache -----------------------------------------------
def test_second_pipeline_into_the_same_folder_is_refused(tmp_path, capsys):
    from rotorlab.pipeline.runner import LOCK_NAME, _open_run_folder, run_folder_lock

    out = tmp_path / "pl"
    first = subprocess.Popen([*CLI, "pipeline", "--tiny", "--workers", "1", "--no-progress", "--out", str(out)],
                             env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        t0 = time.perf_counter()
        while not (out / "stages" / ".experiments.partial").exists() and time.perf_counter() - t0 < 120:
            time.sleep(0.1)
        assert first.poll() is None, "the first pipeline must still be running"
        bad(capsys, "pipeline", "--tiny", "--out", out, says=(str(out), "in use by another rotorlab pipeline",
                                                             f"pid {first.pid}"))
    finally:
        os.killpg(first.pid, signal.SIGKILL)  # the holder cannot clean up; the kernel releases its lock
        first.wait()
    assert (out / LOCK_NAME).exists()  # the stale lock file stays ...
    with run_folder_lock(out):  # ... and does not block the next run, which finds a folder it can resume
        assert _open_run_folder(out, "anteos-p2a2")["vehicle"] == "anteos-p2a2"
    assert not (out / "stages" / "experiments").exists()  # the killed stage never looks finished


def test_unreadable_stage_log_is_a_clean_error(tmp_path):
    from rotorlab.pipeline.runfolder import read_log
    from rotorlab.pipeline.settings import PipelineError

    log = _log(tmp_path)
    log.write_bytes(log.read_bytes()[: len(log.read_bytes()) // 2])
    with pytest.raises(PipelineError, match="not a readable Parquet log"):
        read_log(log)


# -- helpers ---------------------------------------------------------------------------------------------
def _model(tmp_path) -> Path:
    m = tmp_path / "tb.json"
    G, delay_s = published_tf("anteos-p2a2", "testbed")
    m.write_text(json.dumps({"num": G.num[0][0].tolist(), "den": G.den[0][0].tolist(), "dt": 0, "delay_s": delay_s}))
    return m


def _log(tmp_path, n: int = 400, scale: float = 1.0, meta=None) -> Path:
    """A small first-order log (u -> y) in the rotorlab format."""
    from rotorlab.logformat import encode_metadata

    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(n))
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.9 * y[k - 1] + 0.1 * u[k - 1]
    tbl = pa.table({"t": np.arange(n) * 0.02, "u": u * scale, "y": y * scale})
    tbl = tbl.replace_schema_metadata(meta if meta is not None else encode_metadata({"u": "%", "y": "deg/s"}))
    p = tmp_path / "log.parquet"
    pq.write_table(tbl, p)
    return p


def test_helpers_make_a_valid_log(tmp_path, capsys):
    """The fault tests above start from inputs that work: the log identifies, the edited files differ."""
    rc, out, _ = cli(capsys, "ident", _log(tmp_path), "--method", "pi-moesp", "--input", "u", "--output", "y",
                     "--order", "1", "--horizon", "10", "--out", tmp_path / "m.json")
    assert rc == 0 and math.isfinite(json.loads((tmp_path / "m.json").read_text())["vaf"][0])
