"""`rotorlab export-mjcf`: the MJCF of every vehicle in every scene loads in MuJoCo on its own, compiles to the
model the simulator runs (every MjModel array equal, bit for bit) and runs 1 s from the hover keyframe with no
MuJoCo warning and the same trajectory."""

import mujoco
import numpy as np
import pytest

from rotorlab.cli import main
from rotorlab.errors import RotorlabError
from rotorlab.scenes import build_scene, list_scenes
from rotorlab.scenes.export import export
from rotorlab.vehicles import list_vehicles, load_vehicle


def _has_scene(vehicle: str, scene: str) -> bool:
    """A rig scene needs the vehicle's rig table for that axis (``[rig.pitch]``, ``[rig.roll]``)."""
    return not scene.endswith("-rig") or scene.removesuffix("-rig") in load_vehicle(vehicle).rigs


CASES = [(v, s) for v in list_vehicles() for s in list_scenes() if _has_scene(v, s)]
MISSING = [(v, s) for v in list_vehicles() for s in list_scenes() if not _has_scene(v, s)]


def _arrays(m):
    return {n: getattr(m, n) for n in dir(m) if not n.startswith("_") and isinstance(getattr(m, n, None), np.ndarray)}


def _run_1s(m):
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "hover"))
    mujoco.mj_step(m, d, int(round(1.0 / m.opt.timestep)))
    return d


@pytest.mark.parametrize("vehicle,scene", CASES, ids=[f"{v}-{s}" for v, s in CASES])
def test_export_loads_equal_and_steps(vehicle, scene, tmp_path):
    path = tmp_path / f"{vehicle}-{scene}.xml"
    ours = export(vehicle, scene, path)
    loaded = mujoco.MjModel.from_xml_path(str(path))
    a, b = _arrays(ours), _arrays(loaded)
    assert a.keys() == b.keys()
    differ = [n for n in a if a[n].shape != b[n].shape or not np.array_equal(a[n], b[n], equal_nan=True)]
    assert not differ, differ
    d_ours, d_loaded = _run_1s(ours), _run_1s(loaded)
    assert [w.number for w in d_loaded.warning] == [0] * len(d_loaded.warning)
    assert np.array_equal(d_ours.qpos, d_loaded.qpos) and np.array_equal(d_ours.act, d_loaded.act)
    assert d_loaded.time == pytest.approx(1.0)


def test_cli_writes_the_file_and_refuses_a_bad_scene(tmp_path, capsys):
    out = tmp_path / "p2a2.xml"
    assert main(["export-mjcf", "anteos-p2a2", "--scene", "pitch-rig", "--out", str(out)]) == 0
    assert "mujoco.viewer" in capsys.readouterr().out
    assert mujoco.MjModel.from_xml_path(str(out)).nu == build_scene("pitch-rig", "anteos-p2a2").model.nu
    assert main(["export-mjcf", "anteos-p2a2", "--scene", "moon", "--out", str(tmp_path / "x.xml")]) == 2
    err = capsys.readouterr().err
    assert "moon" in err and "pitch-rig" in err and "Traceback" not in err
    assert not (tmp_path / "x.xml").exists()


def test_docstring_example_runs():
    import doctest

    from rotorlab.scenes import export as module

    assert doctest.testmod(module, optionflags=doctest.ELLIPSIS).failed == 0


@pytest.mark.parametrize("vehicle,scene", MISSING, ids=[f"{v}-{s}" for v, s in MISSING])
def test_a_rig_scene_of_a_vehicle_without_that_rig_is_refused(vehicle, scene):
    with pytest.raises(RotorlabError, match=scene.removesuffix("-rig")):
        build_scene(scene, vehicle)
