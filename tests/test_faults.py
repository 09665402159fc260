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
ENV = dict(os.environ)  # as the user's shell gives it: a child picks its own OpenGL backend (rotorlab.glbackend)
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
    ``wait_for()`` holds, and return the finished process. The child starts with SIGINT's default action, as
    from a terminal: a suite run from a background job inherits SIGINT ignored, and Python then never raises
    KeyboardInterrupt."""
    p = subprocess.Popen(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
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


# == issue 26, deliverable 7: every fault class fixed at its root ===============================================
def _cli_subprocess(*argv, timeout=120):
    """The CLI as a user runs it, in a subprocess (a fault that hangs or fills the memory must not take the test
    process with it): returns (exit status, stdout, stderr)."""
    r = subprocess.run([*CLI, *map(str, argv)], env=ENV, capture_output=True, text=True, timeout=timeout)
    return r.returncode, r.stdout, r.stderr


def _running(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie waiting to be reaped is not)."""
    try:
        stat_ = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat_.rsplit(")", 1)[1].split()[0] != "Z"


def _children(pid: int) -> list[int]:
    kids = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids += [int(x) for x in (task / "children").read_text().split()]
        except OSError:
            pass
    return kids


def _wait_for_pool_stage(p, out: Path, timeout_s: float = 600.0) -> None:
    """Until the pipeline ``p`` writing ``out`` is in a pool stage (past its experiments, two workers forked) or
    ``timeout_s`` has passed; the callers assert what they need of the state it ends in."""
    t0 = time.perf_counter()
    while not ((out / "stages" / "experiments").exists() and len(_children(p.pid)) >= 2) \
            and time.perf_counter() - t0 < timeout_s:
        time.sleep(0.05)


def _group(pgid: int) -> list[int]:
    """Live processes of the process group ``pgid``."""
    found = []
    for st in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = st.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] != "Z" and int(fields[2]) == pgid:
            found.append(int(st.parent.name))
    return found


def _foreign_vehicle(folder: Path, name: str = "my-quad", gains: str | None = "optimal-testbed") -> Path:
    """A vehicle of one's own: the P2-A2's numbers under another name in ``folder/vehicle.toml``, with the shipped
    gain set ``gains`` as its ``gains/standard.toml`` (none when None)."""
    folder.mkdir(parents=True, exist_ok=True)
    v = folder / "vehicle.toml"
    v.write_text(P2A2.read_text().replace('name = "anteos-p2a2"', f'name = "{name}"', 1))
    if gains:
        (folder / "gains").mkdir(exist_ok=True)
        (folder / "gains" / "standard.toml").write_bytes((P2A2.parent / "gains" / f"{gains}.toml").read_bytes())
    return v


# -- errors cross process boundaries intact ----------------------------------------------------------------
def _project_exception_classes() -> list[type]:
    import importlib
    import pkgutil

    import rotorlab

    found = {}
    for pkg_name in ("rotorlab", "rotorlab.sim", "rotorlab.ident", "rotorlab.tune", "rotorlab.vehicles",
                     "rotorlab.scenes"):
        pkg = importlib.import_module(pkg_name)
        mods = [pkg] + [importlib.import_module(m.name) for m in pkgutil.walk_packages(pkg.__path__, f"{pkg_name}.")
                        if not m.name.endswith("__main__")]
        for mod in mods:
            for obj in vars(mod).values():
                if (isinstance(obj, type) and issubclass(obj, BaseException)
                        and obj.__module__.startswith(rotorlab.__name__)):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return [found[k] for k in sorted(found)]


def _instance(cls):
    """An instance of ``cls`` from its own signature: every required positional argument filled."""
    import inspect

    args = []
    for p in list(inspect.signature(cls.__init__).parameters.values())[1:]:
        if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            args.append(["b", "a"] if p.name == "valid" else f"<{p.name}>")
    return cls(*args)


def test_every_project_exception_survives_pickling():
    """A pool worker's error reaches the parent pickled: every exception class of the project (walked, not
    listed) round-trips with its type, message and fields, whatever its __init__ takes."""
    import pickle

    from rotorlab.errors import UnknownNameError

    classes = _project_exception_classes()
    names = {c.__name__ for c in classes}
    assert {"ConfigError", "UnknownNameError", "DataError", "CLIError", "ExecutorError", "PipelineError",
            "Diverged"} <= names, names
    cases = [_instance(c) for c in classes]
    cases += [ConfigError("too big", file="v.toml", field="airframe.mass_kg", expected="<= 1000", got=10**5000),
              UnknownNameError("vehicle", "my-quad", ["anteos-p2a2"])]
    for exc in cases:
        back = pickle.loads(pickle.dumps(exc))
        assert type(back) is type(exc) and str(back) == str(exc) and back.args == exc.args, exc
        assert vars(back) == vars(exc), exc
    assert cases[-2].field == "airframe.mass_kg" and "an integer of about 5000 digits" in str(cases[-2])


def _raise_unknown(i):
    from rotorlab.errors import UnknownNameError

    raise UnknownNameError("gain set of my-quad", f"set{i}", ["standard"])


def test_a_workers_error_reaches_the_parent_intact():
    """The measured crash: UnknownNameError raised in a pool worker could not be unpickled in the parent."""
    from rotorlab.errors import UnknownNameError
    from rotorlab.executor import LocalExecutor

    with LocalExecutor(2) as ex, pytest.raises(UnknownNameError, match=r"unknown gain set of my-quad 'set\d'"):
        ex.map(_raise_unknown, [1, 2])


# -- data loss: outputs never overwrite inputs -------------------------------------------------------------
def _run_folder(tmp_path, name="run") -> Path:
    rc = main(["run", "rest", "--scene", "pitch-rig", "--duration", "0.1", "--out", str(tmp_path / name)])
    assert rc == 0
    return tmp_path / name


@pytest.mark.parametrize("case", ["ident", "ident-symlink", "ident-hardlink", "ident-cv", "plot-log", "plot-json",
                                  "compare", "bode", "tune-start", "tune-start-readonly", "tune-model", "tune-spec"])
def test_an_output_that_is_an_input_is_refused(tmp_path, capsys, case):
    log, model = _log(tmp_path), _model(tmp_path)
    ident = ["ident", log, "--method", "pi-moesp", "--input", "u", "--output", "y", "--order", "1",
             "--horizon", "10"]
    tune = ["tune", "--model", model, "--spec", "anteos-p2a2", "--starts", "1", "--max-iter", "1", "--jobs", "1"]
    gains = tmp_path / "g.toml"
    gains.write_bytes((P2A2.parent / "gains" / "optimal-testbed.toml").read_bytes())
    if case.startswith("ident"):
        victim = log
        if case == "ident-symlink":
            (tmp_path / "m.json").symlink_to(log)
            argv = [*ident, "--out", tmp_path / "m.json"]
        elif case == "ident-hardlink":
            os.link(log, tmp_path / "m.json")
            argv = [*ident, "--out", tmp_path / "m.json"]
        elif case == "ident-cv":
            victim = tmp_path / "cv.parquet"
            victim.write_bytes(log.read_bytes())
            argv = [*ident, "--cv-log", victim, "--out", victim]
        else:
            argv = [*ident, "--out", log]
    elif case.startswith("plot") or case == "compare":
        run = _run_folder(tmp_path)
        victim = run / ("run.json" if case == "plot-json" else "log.parquet")
        argv = (["plot", run, "--out", victim] if case.startswith("plot")
                else ["compare", run, _run_folder(tmp_path, "other"), "--out", victim])
    elif case == "bode":
        victim, argv = model, ["bode", model, "--out", model]
    elif case.startswith("tune-start"):
        victim, argv = gains, [*tune, "--start", gains, "--out", gains]
        if case.endswith("readonly"):
            gains.chmod(0o444)
    elif case == "tune-model":
        victim, argv = model, [*tune, "--start", gains, "--out", model]
    else:
        victim = tmp_path / "spec.toml"
        victim.write_bytes(SPEC.read_bytes())
        argv = [*tune[:4], victim, *tune[5:], "--start", gains, "--out", victim]
    before = victim.read_bytes()
    bad(capsys, *argv, says=("--out", "the output is the input file", "expected an output path"))
    assert victim.read_bytes() == before


def test_an_atomic_write_never_replaces_an_input_of_the_running_command(tmp_path):
    """The last line of defence, whatever the command: while a command runs, an input read through the one
    reader (or noted) cannot be replaced by an atomic write; outside a command nothing is recorded."""
    from rotorlab.config import read_toml

    g = tmp_path / "g.toml"
    g.write_bytes((P2A2.parent / "gains" / "standard.toml").read_bytes())
    with atomic.guarding_inputs():
        read_toml(g, "gains")
        with pytest.raises(ConfigError, match="the output is the input file"):
            atomic.write_text(g, "x = 1\n")
        with pytest.raises(ConfigError, match="the output is the input file"):
            atomic.write_text(tmp_path / "sub" / ".." / "g.toml", "x = 1\n")
        atomic.write_text(tmp_path / "other.toml", "x = 1\n")
    read_toml(g, "gains")
    atomic.write_text(g, "x = 2\n")  # a library caller outside a command
    assert g.read_text() == "x = 2\n"


@pytest.mark.parametrize("argv", [
    ["tune", "--model", "MODEL", "--spec", "anteos-p2a2", "--out", "DIR"],
    ["bode", "MODEL", "--out", "DIR"],
    ["plot", "RUN", "--out", "DIR"],
    ["ident", "LOG", "--method", "pi-moesp", "--input", "u", "--output", "y", "--out", "DIR"],
], ids=["tune", "bode", "plot", "ident"])
def test_an_output_file_that_is_a_folder_names_the_option(tmp_path, capsys, argv):
    (tmp_path / "dir").mkdir()
    subs = {"MODEL": _model(tmp_path), "DIR": tmp_path / "dir", "LOG": _log(tmp_path)}
    if "RUN" in argv:
        subs["RUN"] = _run_folder(tmp_path)
    err = bad(capsys, *[subs.get(a, a) for a in argv], says=("--out", "is an existing folder"))
    assert ".tmp" not in err


def test_run_out_that_is_a_file_names_the_option(tmp_path, capsys):
    f = tmp_path / "f"
    f.write_text("mine")
    bad(capsys, *run_rest(P2A2, tmp_path)[:-1], f, says=("--out", "is an existing file"))
    assert f.read_text() == "mine"


def _finished_manifest(out: Path, **changes) -> dict:
    from rotorlab import __version__
    from rotorlab.pipeline.settings import FORMAT_VERSION, settings_for

    man = {"format": "rotorlab-pipeline", "format_version": FORMAT_VERSION, "rotorlab_version": __version__,
           "vehicle": "anteos-p2a2", "seed": 0, "level": "tiny", "settings": settings_for("tiny"),
           "stages": {"experiments": {"hash": "h", "output_hash": "o", "seconds": 1.0}}}
    man.update(changes)
    out.mkdir(parents=True)
    (out / "manifest.json").write_text(json.dumps(man))
    return man


@pytest.mark.parametrize("argv,says", [
    (["--seed", "1"], ("with seed 0 (--seed), not 1",)),
    (["--n-mc", "7"], ("--n-boot/--n-mc", "'n_mc': 20", "'n_mc': 7")),
    (["--quick"], ("with level tiny", "not quick")),
], ids=["seed", "n-mc", "level"])
def test_pipeline_into_a_folder_of_another_run_is_refused(tmp_path, capsys, argv, says):
    """Re-running into a finished folder with another --seed (or size, or level) replaced its results without a
    word; it is refused, the folder untouched. The same settings resume (the pipeline tests)."""
    out = tmp_path / "pl"
    _finished_manifest(out)
    before = (out / "manifest.json").read_bytes()
    args = ["pipeline", "--out", out, *argv] + ([] if "--quick" in argv else ["--tiny"])
    bad(capsys, *args, says=(str(out), "re-running into it would replace its results", *says))
    assert (out / "manifest.json").read_bytes() == before and sorted(p.name for p in out.iterdir()) == \
        ["manifest.json"]


# -- kill: workers die with their parent, the lock is the pipeline's only, SIGTERM writes what it has -------
def test_pool_workers_die_with_a_killed_parent(tmp_path):
    code = ("import os, sys, time\n"
            "from rotorlab.executor import LocalExecutor\n"
            "def nap(i):\n    time.sleep(120)\n"
            "ex = LocalExecutor(2)\n"
            "import threading\n"
            "threading.Thread(target=ex.map, args=(nap, [1, 2]), daemon=True).start()\n"
            "time.sleep(600)\n")
    p = subprocess.Popen([sys.executable, "-c", code], env=ENV, start_new_session=True)
    try:
        t0 = time.perf_counter()
        while len(_children(p.pid)) < 2 and time.perf_counter() - t0 < 60:
            time.sleep(0.1)
        workers = _children(p.pid)
        assert len(workers) >= 2, "the pool did not start"
        os.kill(p.pid, signal.SIGKILL)  # the parent only: the kernel must take its workers
        p.wait()
        t0 = time.perf_counter()
        while any(map(_running, workers)) and time.perf_counter() - t0 < 10:
            time.sleep(0.1)
        assert not any(map(_running, workers)), "pool workers outlived their killed parent"
    finally:
        for pid in _group(p.pid):
            os.kill(pid, signal.SIGKILL)


def test_the_run_folder_lock_is_never_held_by_a_forked_child(tmp_path):
    """A forked worker that outlives its killed pipeline held the flock it inherited and refused the re-run,
    naming the dead pid. The lock lives only in the pipeline process."""
    from rotorlab.pipeline.runner import run_folder_lock

    out = tmp_path / "pl"
    code = ("import os, sys, time\nfrom pathlib import Path\n"
            "from rotorlab.pipeline.runner import run_folder_lock\n"
            f"with run_folder_lock(Path({str(out)!r})):\n"
            "    pid = os.fork()\n"
            "    if pid == 0:\n        os.write(1, b'child running\\n')\n        time.sleep(120)\n"
            "        os._exit(0)\n"
            "    os.write(1, f'{pid}\\n'.encode())\n    time.sleep(120)\n")
    p = subprocess.Popen([sys.executable, "-c", code], env=ENV, stdout=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        # both lines before the kill: the child has returned from fork (its at-fork handlers have run) and lives;
        # on a loaded machine the parent may print first while the child has not been scheduled yet (one write a
        # line: a pipe write that small is atomic, the two lines never interleave)
        lines = [p.stdout.readline().strip() for _ in range(2)]
        assert "child running" in lines, lines
        child = int(next(x for x in lines if x != "child running"))
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        assert _running(child)  # a plain fork: the orphan lives on ...
        with run_folder_lock(out):  # ... and does not hold the lock
            pass
    finally:
        for pid in _group(p.pid):
            os.kill(pid, signal.SIGKILL)


def test_a_lock_left_to_a_dead_pipelines_leftovers_is_recognised(tmp_path):
    """Leftovers of an older rotorlab (workers that kept the flock) are named, with their pids, instead of the
    dead pipeline as if it were running."""
    from rotorlab.pipeline.runner import LOCK_NAME, run_folder_lock
    from rotorlab.pipeline.settings import PipelineError

    out = tmp_path / "pl"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out / LOCK_NAME).write_text(f"pid {int(dead.stdout)} on {socket.gethostname()}, started then\n")
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time\n"
                               f"fd = os.open({str(out / LOCK_NAME)!r}, os.O_RDWR)\n"
                               "fcntl.flock(fd, fcntl.LOCK_EX)\nprint('held', flush=True)\ntime.sleep(120)\n"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(PipelineError, match=rf"no longer running.*pid\(s\) {holder.pid} still hold"), \
                run_folder_lock(out):
            pass
    finally:
        holder.kill()
        holder.wait()


def test_sigterm_to_run_writes_the_partial_log(tmp_path):
    out = tmp_path / "r"
    p = subprocess.Popen([*CLI, "run", "hover", "--duration", "600", "--out", str(out)], env=ENV,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    t0 = time.perf_counter()
    while not out.exists() and time.perf_counter() - t0 < 120:
        time.sleep(0.1)
    time.sleep(3.0)
    p.send_signal(signal.SIGTERM)  # to the process only, as `kill PID` or a job scheduler does
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    assert "Traceback" not in err and "terminated (SIGTERM)" in err
    info = json.loads((out / "run.json").read_text())
    assert info["stopped"] == "interrupted (Ctrl-C)" and 0 < info["rows"] < 30000
    assert pq.read_table(out / "log.parquet").num_rows == info["rows"]


def test_sigkill_of_a_pipeline_leaves_no_process_and_the_rerun_resumes_with_identical_numbers(tmp_path):
    """The acceptance test: a tiny pipeline killed with SIGKILL in its pool stage leaves no rotorlab process;
    the same command then resumes (completed stages cached) and every stage's output hash equals an
    uninterrupted run's."""
    cmd = [*CLI, "pipeline", "--tiny", "--workers", "2", "--no-progress", "--seed", "3"]
    ref, out = tmp_path / "ref", tmp_path / "killed"
    subprocess.run([*cmd, "--out", str(ref)], env=ENV, check=True, capture_output=True, timeout=1200)
    p = subprocess.Popen([*cmd, "--out", str(out)], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True)
    try:
        _wait_for_pool_stage(p, out)
        assert p.poll() is None and len(_children(p.pid)) >= 2, "no pool stage caught running"
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        t0 = time.perf_counter()
        while _group(p.pid) and time.perf_counter() - t0 < 10:
            time.sleep(0.1)
        assert _group(p.pid) == [], "processes of the killed pipeline survive"
    finally:
        for pid in _group(p.pid):
            os.kill(pid, signal.SIGKILL)
    r = subprocess.run([*cmd, "--out", str(out)], env=ENV, capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "experiments  cached" in r.stdout
    man_ref, man = (json.loads((d / "manifest.json").read_text())["stages"] for d in (ref, out))
    assert set(man) == set(man_ref)
    for stage in man_ref:
        if stage != "report":  # the report records the run's timings
            assert man[stage]["output_hash"] == man_ref[stage]["output_hash"], stage
    s_ref, s = (json.loads((d / "report" / "summary.json").read_text()) for d in (ref, out))
    assert s["h_lim"] == s_ref["h_lim"]


# -- escape: names from files never become paths --------------------------------------------------------------
@pytest.mark.parametrize("name", ["../../escaped", "a/b", "..", "", ".hidden", "x" * 65, "a\nb"])
def test_a_vehicle_name_that_is_not_a_safe_name_is_refused(tmp_path, capsys, monkeypatch, name):
    monkeypatch.chdir(tmp_path)
    v = edited(tmp_path, P2A2, 'name = "anteos-p2a2"', f"name = {json.dumps(name)}")
    bad(capsys, "run", "rest", "--scene", "pitch-rig", "--vehicle", v, "--duration", "0.04",
        says=(str(v), "'vehicle.name'", "letters, digits"))
    assert not (tmp_path.parent / "rest-escaped-seed0").exists() and not (tmp_path / "runs").exists()


def test_a_spec_vehicle_that_is_a_path_is_refused(tmp_path, capsys):
    evil = tmp_path / "evil"
    (evil / "gains").mkdir(parents=True)
    (evil / "gains" / "standard.toml").write_bytes((P2A2.parent / "gains" / "standard.toml").read_bytes())
    rel = os.path.relpath(evil, VEHICLES_DIR)
    s = edited(tmp_path, SPEC, 'vehicle = "anteos-p2a2"', f'vehicle = "{rel}"', "spec.toml")
    bad(capsys, "tune", "--model", _model(tmp_path), "--spec", s, "--out", tmp_path / "o.toml",
        says=(str(s), "'meta.vehicle'", "letters, digits", rel))


def test_a_gain_set_name_is_never_a_path(tmp_path):
    from rotorlab.errors import UnknownNameError
    from rotorlab.vehicles import gains_path

    (P2A2.parent / "gains" / "standard.toml").resolve()
    with pytest.raises(UnknownNameError, match="valid: optimal-flight, optimal-testbed, standard"):
        gains_path("anteos-p2a2", "../../anteos-a2minib/gains/optimal")


# -- own vehicles work everywhere a shipped one does ---------------------------------------------------------
def test_a_vehicle_of_ones_own_flies_the_gain_sets_beside_its_file(tmp_path, capsys):
    """`run --vehicle my.toml` without --gains looked the default set up by the file's [vehicle] name among the
    shipped vehicles (unknown vehicle 'my-quad'); it flies gains/standard.toml beside the file."""
    from rotorlab.gains import load_gains

    v = _foreign_vehicle(tmp_path / "my-quad")
    rc, _, _ = cli(capsys, *run_rest(v, tmp_path))
    assert rc == 0
    info = json.loads((tmp_path / "r" / "run.json").read_text())
    assert info["vehicle"] == "my-quad" and info["gains"] == "standard"
    flown = info["gain_values"]["pitch"]["inner"]["kp"]
    assert flown == load_gains(P2A2.parent / "gains" / "optimal-testbed.toml")["pitch"].inner.kp
    assert flown != load_gains(P2A2.parent / "gains" / "standard.toml")["pitch"].inner.kp
    rc, _, _ = cli(capsys, "run", "hover", "--vehicle", v, "--duration", "0.2", "--out", tmp_path / "h",
                   "--option", "switch_to=standard")
    assert rc in (0, 1)


def test_a_vehicle_of_ones_own_without_gain_sets_says_how_to_give_them(tmp_path, capsys):
    v = _foreign_vehicle(tmp_path / "bare", gains=None)
    bad(capsys, *run_rest(v, tmp_path), says=("vehicle 'my-quad'", "has no gain sets", "--gains FILE.toml",
                                              str(tmp_path / "bare" / "gains" / "standard.toml")))


def test_a_modified_copy_of_a_shipped_vehicle_keeps_its_gain_sets(tmp_path, capsys):
    v = edited(tmp_path, P2A2, "mass_kg = 5.0 ", "mass_kg = 5.1 ")
    assert cli(capsys, *run_rest(v, tmp_path))[0] == 0
    assert json.loads((tmp_path / "r" / "run.json").read_text())["gains"] == "standard"


# -- hangs: only regular files, bounded sizes and counts ----------------------------------------------------
@pytest.mark.parametrize("kind", ["vehicle-fifo", "gains-fifo", "model-fifo", "spec-fifo", "vehicle-zero",
                                  "model-zero", "vehicle-huge"])
def test_inputs_that_would_hang_or_fill_the_memory_are_refused_at_once(tmp_path, kind):
    what, how = kind.split("-")
    p = tmp_path / (f"in.{'json' if what == 'model' else 'toml'}")
    if how == "fifo":
        os.mkfifo(p)
    elif how == "zero":
        p.symlink_to("/dev/zero")
    else:
        with open(p, "wb") as fh:
            fh.truncate(33 * 2**20)
    argv = {"vehicle": ["run", "rest", "--scene", "pitch-rig", "--duration", "0.04", "--vehicle", p],
            "gains": ["run", "rest", "--scene", "pitch-rig", "--duration", "0.04", "--gains", p],
            "model": ["bode", p],
            "spec": ["tune", "--model", _model(tmp_path), "--spec", p]}[what]
    t0 = time.perf_counter()
    rc, out, err = _cli_subprocess(*argv, "--out", tmp_path / "o", timeout=60)
    assert rc == 2 and "Traceback" not in err, err
    says = {"fifo": "got 'a FIFO'", "zero": "got 'a device'", "huge": "too large"}[how]
    assert str(p) in err and says in err, err
    assert time.perf_counter() - t0 < 60


@pytest.mark.parametrize("argv,flag", [
    (["montecarlo", "rest", "--n", "1000000000000"], "--n"),
    (["montecarlo", "rest", "--n", "1e12"], "--n"),
    (["montecarlo", "rest", "--workers", "5000"], "--workers"),
    (["pipeline", "--tiny", "--n-mc", "1000000000"], "--n-mc"),
    (["pipeline", "--tiny", "--n-boot", "1e9"], "--n-boot"),
    (["pipeline", "--tiny", "--workers", "300"], "--workers"),
    (["tune", "--model", "m.json", "--spec", "anteos-p2a2", "--out", "g.toml", "--jobs", "300"], "--jobs"),
    (["tune", "--model", "m.json", "--spec", "anteos-p2a2", "--out", "g.toml", "--starts", "1000000000"],
     "--starts"),
], ids=lambda x: x if isinstance(x, str) else " ".join(x[:1] + x[-2:]))
def test_every_count_is_bounded_before_work_starts(tmp_path, capsys, monkeypatch, argv, flag):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}: expected a whole number in [1, " in err, err
    assert not (tmp_path / "runs").exists()


def test_a_dask_scheduler_without_workers_times_out(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    from rotorlab.executor import ExecutorError, get_executor

    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        addr = cluster.scheduler_address.removeprefix("tcp://")
        t0 = time.perf_counter()
        with pytest.raises(ExecutorError, match=f"dask://{addr}|{addr}.*has no workers.*dask worker"):
            get_executor(f"dask://{addr}", timeout_s=2.0)
        assert time.perf_counter() - t0 < 30


# -- tracebacks: every parser guarded against depth, size and number length ---------------------------------
def _deep(kind: str) -> str:
    return {"toml-array": "[x]\ny = " + "[" * 100_000 + "]" * 100_000 + "\n",
            "toml-table": "[x]\ny = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n",
            "toml-33": "[x]\ny = " + "[" * 33 + "]" * 33 + "\n"}[kind]


@pytest.mark.parametrize("kind", ["toml-array", "toml-table", "toml-33"])
def test_deeply_nested_toml_is_an_error(tmp_path, capsys, kind):
    v = tmp_path / "vehicle.toml"
    v.write_text(P2A2.read_text() + "\n" + _deep(kind))
    bad(capsys, *run_rest(v, tmp_path), says=(str(v), "nested too deeply"))


@pytest.mark.parametrize("doc,says", [
    ('{"num": ' + "[" * 100_000 + "]" * 100_000 + ', "den": [1, 1]}', "nested too deeply"),
    ('{"num": [' + "9" * 5000 + '], "den": [1, 1], "dt": 0}', "'num'"),
    ('{"num": [' + "9" * 400 + '], "den": [1, 1], "dt": 0}', "'num'"),
    ('{"num": [1], "den": [1, 1], "dt": ' + "9" * 5000 + "}", "'dt'"),
    ('{"num": [1], "den": [1, 1e999], "dt": 0}', "'den'"),
    ('{"num": [0, 0], "den": [1, 2, 3], "dt": 0}', "the model is zero"),
    ('[1, 2]', "the top level must be an object"),
    ('{"num": [1], "den": [1' + ", 0.5" * 300 + '], "dt": 0.02}', "model order too high"),
], ids=["deep", "5000-digits", "400-digits", "dt-5000-digits", "inf", "zero", "list", "order-300"])
def test_bad_model_json_is_an_error(tmp_path, capsys, doc, says):
    m = tmp_path / "m.json"
    m.write_text(doc)
    err = bad(capsys, "bode", m, "--out", tmp_path / "b.png", says=(str(m), says))
    assert len(err) < 1000


@pytest.mark.parametrize("field,old,new", [
    ("airframe.mass_kg", "mass_kg = 5.0 ", "mass_kg = " + "9" * 5000 + " "),
    ("airframe.mass_kg", "mass_kg = 5.0 ", "mass_kg = " + "9" * 400 + " "),
    ("flight_software.rate_hz", "[commands]", "[flight_software]\nrate_hz = 333\n\n[commands]"),
    ("flight_software.rate_hz", "[commands]", "[flight_software]\nrate_hz = 1e5\n\n[commands]"),
], ids=["5000-digits", "400-digits", "rate-333", "rate-1e5"])
def test_vehicle_numbers_that_crashed_are_errors(tmp_path, capsys, field, old, new):
    v = edited(tmp_path, P2A2, old, new)
    err = bad(capsys, *run_rest(v, tmp_path), says=(str(v), f"'{field}'"))
    assert len(err) < 1000


@pytest.mark.parametrize("what", ["corrupt", "deep", "list", "binary"])
@pytest.mark.parametrize("command", ["plot", "view", "compare"])
def test_a_corrupt_run_json_is_an_error(tmp_path, capsys, what, command):
    run = _run_folder(tmp_path)
    (run / "run.json").write_bytes({"corrupt": b'{"scenario": ', "deep": b"[" * 100_000 + b"]" * 100_000,
                                    "list": b"[1, 2]", "binary": b"\xff\xfe\x00garbage"}[what])
    argv = {"plot": ["plot", run, "--out", tmp_path / "p.png"], "view": ["view", run, "--print"],
            "compare": ["compare", run, _run_folder(tmp_path, "other"), "--out", tmp_path / "c.png"]}[command]
    bad(capsys, *argv, says=(str(run / "run.json"),))


def test_a_deeply_nested_option_is_an_error(tmp_path, capsys):
    bad(capsys, *run_rest(P2A2, tmp_path), "--option", "level=" + "[" * 5000 + "]" * 5000,
        says=("--option level", "nested at most"))


# -- silently wrong ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("output", ["q", "theta_ref", "theta", "rotor_pct"])
def test_a_controller_that_sets_a_measured_signal_is_refused(tmp_path, capsys, output):
    """A controller output named 'q' replaced the measured rate in the log (after the loops had used it)."""
    c = tmp_path / "c.json"
    c.write_text(json.dumps({"format": "rotorlab-controller/1", "dt_s": 0.02, "inputs": ["theta"],
                             "outputs": [output], "A": [[0.0]], "B": [[0.0]], "C": [[0.0]], "D": [[1.0]]}))
    bad(capsys, *run_rest(P2A2, tmp_path), "--controller", c, says=(str(c), "'outputs'", "u_lon", output))


def _flight_software_with(plugin):
    """The P2-A2's flight software for the rest scenario with ``plugin`` appended."""
    from rotorlab.gains import load_gains
    from rotorlab.sim import scenarios
    from rotorlab.sim.runner import make_flight_software
    from rotorlab.vehicles import load_vehicle

    v = load_vehicle("anteos-p2a2")
    ctx = scenarios.Context(vehicle=v, scene="pitch-rig", gains=None, seed=0, duration_s=1.0, options={},
                            dt_s=v.control_dt_s)
    fs = make_flight_software(v, load_gains(P2A2.parent / "gains" / "standard.toml"), scenarios.get("rest").setup(ctx))
    fs.plugins.append(plugin)
    return fs, {k: 0.0 for k in ("phi", "theta", "psi", "p", "q", "r")}


def test_a_plugin_cannot_overwrite_a_signal_of_the_flight_software():
    """The same rule for any plug-in: commands and new names only (the log keeps the true measurement)."""
    from rotorlab.sim.control.plugins import CallbackPlugin

    fs, meas = _flight_software_with(CallbackPlugin(lambda t, s: {"estimate": 1.0, "q": 0.0}))
    with pytest.raises(ConfigError, match="returns 'q', a signal of the flight software"):
        fs.step(0.0, meas)


def test_a_plugin_may_log_its_own_signals_every_tick():
    from rotorlab.sim.control.plugins import CallbackPlugin

    fs, meas = _flight_software_with(CallbackPlugin(lambda t, s: {"estimate": t, "u_lon": 1.5}))
    for k in range(3):
        sig = fs.step(k * fs.dt, meas)
    assert sig["estimate"] == 2 * fs.dt and sig["u_lon"] == 1.5


def test_montecarlo_delay_spread_stays_within_the_files_range(tmp_path, capsys):
    """--vary delay=5 drew 3.4-4.0 s delays on a vehicle whose file caps rotor.delay_s at 1 s."""
    bad(capsys, "montecarlo", "rest", "--n", "2", "--vary", "delay=5", "--out", tmp_path / "mc",
        says=("--vary delay", "at most 0.94 s", "rotor.delay_s", "[0, 1] s", "got 5"))
    bad(capsys, "montecarlo", "gust", "--n", "2", "--vary", "wind=1e300", "--out", tmp_path / "mc",
        says=("--vary wind", "at most 50 m/s"))
    assert not (tmp_path / "mc").exists()


# -- vague: messages name the file's field and the rule ------------------------------------------------------
def test_a_mass_the_rotors_cannot_carry_names_mass_kg(tmp_path, capsys):
    v = edited(tmp_path, P2A2, "mass_kg = 5.0 ", "mass_kg = 1000 ")
    err = bad(capsys, *run_rest(v, tmp_path), says=(str(v), "'airframe.mass_kg'", "rotor.thrust_slope_N_per_rad",
                                                    "got 1000"))
    assert "hover_collective_pct" not in err


def test_an_empty_tune_list_names_the_field(tmp_path, capsys):
    s = edited(tmp_path, SPEC, 'tune = ["outer.kp", "outer.kd", "outer.tf", "inner.kp", "inner.ki", "inner.kd", '
                               '"inner.tf"]', "tune = []", "spec.toml")
    err = bad(capsys, "tune", "--model", _model(tmp_path), "--spec", s, "--out", tmp_path / "o.toml",
              says=(str(s), "'cascade.tune'", "nothing to tune"))
    assert "reshape" not in err


@pytest.mark.parametrize("field,old,new", [
    ("airframe.arm_m", "arm_m = 0.415 ", "arm_m = 1e300 "),
    ("rotor.radius_m", "radius_m = 0.27 ", "radius_m = 1e-300 "),
    ("rotor.rotor_speed_rad_s", "rotor_speed_rad_s = 316.0 ", "rotor_speed_rad_s = 1e300 "),
    ("rotor.blade_pitch_per_pct_rad", "blade_pitch_per_pct_rad = 0.0017143 ", "blade_pitch_per_pct_rad = 1e-300 "),
    ("commands.limit_pct", "limit_pct = 30.0 ", "limit_pct = 1e300 "),
    ("airframe.cp_offset_m", "cp_offset_m = [0.0, 0.0, 0.03]", "cp_offset_m = [0.0, 0.0, 1e300]"),
])
def test_implausible_magnitudes_name_the_field(tmp_path, capsys, field, old, new):
    v = edited(tmp_path, P2A2, old, new)
    bad(capsys, *run_rest(v, tmp_path), says=(str(v), f"'{field}'", "a magnitude in [1e-09, 1e+06]"))


def test_pipeline_of_a_vehicle_without_gain_sets_says_so_before_work(tmp_path, capsys):
    v = _foreign_vehicle(tmp_path / "bare", gains=None)
    bad(capsys, "pipeline", "--tiny", "--vehicle", v, "--out", tmp_path / "pl",
        says=("'standard' gain set", str(tmp_path / "bare" / "gains"), "has no gain sets"))
    assert not (tmp_path / "pl").exists()


def test_montecarlo_duration_is_checked_before_the_runs(tmp_path, capsys):
    """A duration no run can take failed in every worker and was reported as 100 % stopped early, exit 0."""
    bad(capsys, "montecarlo", "rest", "--n", "2", "--duration", "1e9", "--out", tmp_path / "mc",
        says=("'duration'", "over half the available memory"))
    assert not list(tmp_path.glob("mc/*.parquet"))


def test_sigterm_to_a_pipeline_stops_its_workers_and_keeps_its_stages(tmp_path):
    """SIGTERM (`kill PID`, a job scheduler) left the two workers computing for minutes; it is handled as
    Ctrl-C: the workers are stopped, completed stages kept, exit 143."""
    out = tmp_path / "pl"
    p = subprocess.Popen([*CLI, "pipeline", "--tiny", "--workers", "2", "--no-progress", "--seed", "3", "--out",
                          str(out)], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        _wait_for_pool_stage(p, out)
        assert p.poll() is None, "the pipeline ended before a pool stage was caught"
        p.send_signal(signal.SIGTERM)
        text, err = p.communicate(timeout=120)
        assert p.returncode == 143, err
        assert "Traceback" not in text + err and "completed stages are kept" in text
        t0 = time.perf_counter()
        while _group(p.pid) and time.perf_counter() - t0 < 10:
            time.sleep(0.1)
        assert _group(p.pid) == []
        assert (out / "stages" / "experiments" / "stage.json").exists()
    finally:
        for pid in _group(p.pid):
            os.kill(pid, signal.SIGKILL)


@pytest.mark.parametrize("scenario,option,says", [
    ("hover", "wind_mps=1e300", ("'options.wind_mps'", "magnitude at most 1e+06")),
    ("gust", "mean_wind_mps=-1e300", ("'options.mean_wind_mps'", "magnitude at most 1e+06")),
    ("hover", "wind_mps=1000", ("'V_mps'", "(0, 340] m/s", "mean wind")),
])
def test_scenario_options_beyond_any_flight_are_refused(tmp_path, capsys, scenario, option, says):
    """wind_mps = 1e300 overflowed the turbulence filter into a traceback."""
    bad(capsys, "run", scenario, "--duration", "1", "--option", option, "--out", tmp_path / "r", says=says)


@pytest.mark.parametrize("case,says", [
    ("spec-dt", ("'cascade.dt'", "0 (continuous design) or at least 0.0001 s", "got 1e-300")),
    ("delay-samples", ("delay of 1 s is 1e+04 samples", "cascade.dt = 0.0001 s", "at most 200")),
    ("start-kp", ("'pitch.outer.kp'", "a magnitude of at most 1e+06", "got 1e+300")),
])
def test_tuning_sizes_and_gains_beyond_reason_are_refused(tmp_path, capsys, case, says):
    """A 1e-300 s cycle reached numpy as "Maximum allowed dimension exceeded"; kp = 1e300 as "the interconnection
    is not well posed"; a 1 s delay at 0.1 ms is 10000 states of every loop analysed."""
    model, spec, start = _model(tmp_path), SPEC, P2A2.parent / "gains" / "standard.toml"
    if case == "spec-dt":
        spec = edited(tmp_path, SPEC, "dt = 0.02 ", "dt = 1e-300 ", "spec.toml")
    elif case == "delay-samples":
        spec = edited(tmp_path, SPEC, "dt = 0.02 ", "dt = 0.0001 ", "spec.toml")
        doc = json.loads(model.read_text())
        model.write_text(json.dumps({**doc, "delay_s": 1.0}))
    else:
        start = tmp_path / "g.toml"
        text = (P2A2.parent / "gains" / "standard.toml").read_text()
        import re

        start.write_text(re.sub(r"kp = [0-9.]+", "kp = 1e300", text, count=1))
    bad(capsys, "tune", "--model", model, "--spec", spec, "--start", start, "--out", tmp_path / "o.toml",
        "--starts", "1", "--max-iter", "1", "--jobs", "1", says=says)
