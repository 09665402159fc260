"""Packaging: setup.py's discovery lists every package of the source tree (found here independently, by
walking the mapped folders for __init__.py files), so nothing that works under `pip install -e` is left out of
the wheel. The wheel itself is built and listed by .ci/check_wheel.py in CI."""

import os
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_discovery_finds_every_package_of_the_tree(repo_module):
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    walked = set()
    for name, folder in mapping.items():
        for dirpath, dirnames, filenames in os.walk(ROOT / folder):
            dirnames[:] = [d for d in dirnames if d != "__pycache__" and not d.startswith(".")]
            if "__init__.py" in filenames:
                rel = Path(dirpath).relative_to(ROOT / folder).parts
                walked.add(".".join((name, *rel)))
    found = set(repo_module("setup.py").discover(ROOT))  # not run as __main__: setup() is not called
    assert found == walked
    assert {"rotorlab.pipeline.stages", "rotorlab.sim.scenarios", "rotorlab.tune"} <= found


def test_no_hand_written_package_list():
    setuptools_cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "packages" not in setuptools_cfg


def test_pxd_files_are_staged_under_the_installed_names_and_kept_in_step(repo_module, tmp_path):
    """Cython finds a module's .pxd by the module's installed name: ``sim/frames.pxd`` must be visible as
    ``rotorlab/sim/frames.pxd`` on the include path; a package whose folder is its name (``rotorlab/``) needs no
    copy. A copy is rewritten only when the source changed and removed with its source."""
    stage_pxd = repo_module("setup.py")._stage_pxd
    (tmp_path / "sim").mkdir()
    (tmp_path / "rotorlab" / "autopilots").mkdir(parents=True)
    (tmp_path / "sim" / "frames.pxd").write_text("cpdef tuple euler_deg(double w)\n")
    (tmp_path / "rotorlab" / "autopilots" / "px4.pxd").write_text("cdef class RateController:\n    pass\n")
    sources = {"rotorlab.sim.frames": "sim/frames.py", "rotorlab.sim.log": "sim/log.py",
               "rotorlab.autopilots.px4": "rotorlab/autopilots/px4.py"}
    stage = Path(stage_pxd(sources, root=tmp_path))
    staged = stage / "rotorlab" / "sim" / "frames.pxd"
    assert sorted(p.relative_to(stage).as_posix() for p in stage.rglob("*.pxd")) == ["rotorlab/sim/frames.pxd"]
    assert staged.read_text() == "cpdef tuple euler_deg(double w)\n"
    os.utime(staged, ns=(1, 1))
    stage_pxd(sources, root=tmp_path)
    assert staged.stat().st_mtime_ns == 1  # unchanged source: not rewritten (Cython would retranslate)
    (tmp_path / "sim" / "frames.pxd").write_text("cpdef tuple euler_deg(double w, double x)\n")
    stage_pxd(sources, root=tmp_path)
    assert staged.read_text() == "cpdef tuple euler_deg(double w, double x)\n"
    (tmp_path / "sim" / "frames.pxd").unlink()
    stage_pxd(sources, root=tmp_path)
    assert not staged.exists()
