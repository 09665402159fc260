"""Rerun recordings: read the .rrd back and check entity paths, row counts and values against the run."""

import math
import shutil
import sys
import types

import mujoco
import numpy as np
import pytest

from rotorlab.cli import main
from rotorlab.errors import ConfigError
from rotorlab.sim.disturbances.rope_pull import RopePull
from rotorlab.sim.log import RunLog
from rotorlab.sim.poses import PoseTrack
from rotorlab.sim.rerun_log import THRUST_ARROW_M_PER_N, check_rrd_path, record_run
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.simulator import Simulator

rr_chunk = pytest.importorskip("rerun.chunk")


def _chunks(path):
    out = {}
    for ch in rr_chunk.RrdReader(str(path)).stream().to_chunks():
        out.setdefault(ch.entity_path, []).append(ch)
    return out


def _column(chunks, entity, component):
    """Concatenated non-static values of ``component`` at ``entity``, in time order."""
    rows = []
    for ch in chunks[entity]:
        if ch.is_static:
            continue
        d = ch.to_record_batch().to_pydict()
        for t, v in zip(d["sim_time"], d[component]):
            rows.append((t.total_seconds(), v))
    rows.sort(key=lambda r: r[0])
    return [r[0] for r in rows], [r[1] for r in rows]


def _static(chunks, entity, component):
    for ch in chunks[entity]:
        if ch.is_static:
            d = ch.to_record_batch().to_pydict()
            if component in d:
                return d[component][0]
    raise KeyError(component)


@pytest.fixture(scope="module")
def run_and_rrd(tmp_path_factory):
    res = run_scenario("rest", scene="pitch-rig", duration_s=1.0, record_poses=True)
    path = record_run(res, tmp_path_factory.mktemp("rrd") / "rest.rrd")
    return res, path, _chunks(path)


def test_recording_has_the_expected_entities(run_and_rrd):
    res, _, ch = run_and_rrd
    for entity in ("/world/bodies/vehicle_airframe", "/world/bodies/rig_ring", "/world/thrust",
                   "/world/bodies/vehicle_airframe/boxes", "/world/bodies/vehicle_airframe/cylinders",
                   "/signals/angle/theta", "/signals/rate/q", "/signals/command/u_lon", "/signals/angle/theta_ref"):
        assert entity in ch, entity
    assert sum(c.num_rows for c in ch["/signals/angle/theta"] if not c.is_static) == res.log.n == 50


def test_signal_values_match_the_log(run_and_rrd):
    res, _, ch = run_and_rrd
    t, vals = _column(ch, "/signals/angle/theta", "Scalars:scalars")
    np.testing.assert_allclose(t, res.log["t"], atol=1e-9)
    np.testing.assert_allclose([v[0] for v in vals], res.log["theta"], rtol=0, atol=0)


def test_body_poses_and_thrust_arrows_match_the_run(run_and_rrd):
    res, _, ch = run_and_rrd
    poses = res.poses
    b = poses.body_names.index("vehicle/airframe")
    np.testing.assert_allclose(poses.t, res.log["t"])
    _, tr = _column(ch, "/world/bodies/vehicle_airframe", "Transform3D:translation")
    _, q = _column(ch, "/world/bodies/vehicle_airframe", "Transform3D:quaternion")
    # one transform per row (a batch of one)
    np.testing.assert_allclose(np.array([v[0] for v in tr]), poses.xpos[:, b], atol=1e-6)
    np.testing.assert_allclose(np.array([v[0] for v in q]), poses.xquat[:, b][:, [1, 2, 3, 0]], atol=1e-6)
    # four arrows per tick, each thrust * scale long; at the hover trim every rotor carries m g / 4
    _, vec = _column(ch, "/world/thrust", "Arrows3D:vectors")
    assert all(len(v) == 4 for v in vec)
    lengths = np.linalg.norm(np.array(vec[-1]), axis=1)
    np.testing.assert_allclose(lengths, np.abs(poses.thrust_N[-1]) * THRUST_ARROW_M_PER_N, rtol=1e-5)
    np.testing.assert_allclose(poses.thrust_N[0], 5.0 * 9.81 / 4, rtol=0.02)


def test_static_geometry_comes_from_the_model(run_and_rrd):
    res, _, ch = run_and_rrd
    m = res.poses.model
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "vehicle/fuselage")
    half = _static(ch, "/world/bodies/vehicle_airframe/boxes", "Boxes3D:half_sizes")
    assert any(np.allclose(h, m.geom_size[g], atol=1e-6) for h in half)
    radii = _static(ch, "/world/bodies/vehicle_airframe/cylinders", "Cylinders3D:radii")
    assert np.allclose(sorted(radii), [0.27] * 4)  # the four rotor discs, R = 0.27 m [P2-A2]


def test_unwritable_path_fails_before_the_run(tmp_path):
    with pytest.raises(ConfigError, match="rrd"):
        check_rrd_path(tmp_path / "log.txt")
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ConfigError, match="cannot write"):
        check_rrd_path(blocker / "sub" / "run.rrd")
    out = tmp_path / "run"
    assert main(["run", "rest", "--duration", "0.2", "--out", str(out), "--rerun", str(blocker / "x.rrd")]) == 2
    assert not out.exists()  # nothing was simulated


def test_cli_run_rerun_and_view(tmp_path, capsys, monkeypatch):
    out, rrd = tmp_path / "run", tmp_path / "run" / "recording.rrd"
    assert main(["run", "rest", "--duration", "0.4", "--out", str(out), "--rerun", str(rrd)]) == 0
    assert "/world/bodies/vehicle_airframe" in _chunks(rrd)
    capsys.readouterr()
    assert main(["view", str(out), "--print"]) == 0
    assert capsys.readouterr().out.strip().endswith(str(rrd))
    # no viewer beside the interpreter nor on PATH: how to get one, and both ways to open the recording
    monkeypatch.setattr(sys, "executable", str(tmp_path / "no-venv" / "python"))
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert main(["view", str(rrd)]) == 0
    text = capsys.readouterr().out
    assert "nor on PATH" in text and "pip install rerun-sdk" in text
    assert f"rerun {rrd}" in text and f"rotorlab view {rrd} --web" in text


def test_view_makes_a_recording_from_a_plain_run_folder(tmp_path, capsys):
    out = tmp_path / "plain"
    res = run_scenario("rest", scene="pitch-rig", duration_s=0.4, out=out)
    assert main(["view", str(out), "--print"]) == 0
    ch = _chunks(out / "recording.rrd")
    t, vals = _column(ch, "/signals/rate/q", "Scalars:scalars")
    assert len(t) == res.log.n and math.isclose(vals[3][0], res.log["q"][3])
    assert "/world/bodies/vehicle_airframe/boxes" in ch  # static scene rebuilt from run.json


def test_rope_is_recorded_as_a_line_between_its_sites(tmp_path):
    sim = Simulator("pitch-rig", "anteos-p2a2", disturbances=[RopePull(t_pull_s=0.1, ramp_s=0.2)])
    track, log = PoseTrack(sim, 20), RunLog({"theta": "deg"}, 20)
    tip = sim.model.site("vehicle/arm_front_tip").id
    for _ in range(20):
        log.append(sim.time, {"theta": sim.true_attitude_deg()[1]})
        track.record(sim)
        # the rope's path starts or ends at the front-arm tip site, where it is tied
        path = track.tendon_path[track.n - 1, 0, :track.tendon_wrapnum[track.n - 1, 0]]
        assert min(np.linalg.norm(path - sim.data.site_xpos[tip], axis=1)) < 1e-12
        sim.tick()
    res = types.SimpleNamespace(log=log, poses=track.trimmed(), info={})
    ch = _chunks(record_run(res, tmp_path / "rope.rrd"))
    ropes = [e for e in ch if e.startswith("/world/tendons/")]
    assert len(ropes) == 1 and sum(c.num_rows for c in ch[ropes[0]]) == 20
