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
