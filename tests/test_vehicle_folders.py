"""Every vehicle folder is complete: its parameters (vehicle.toml, which loads), a README citing them, a
CHANGELOG.md with at least one version, and a rendered picture (vehicle.png, from docs/render_vehicles.py) that is
a real image of the vehicle, not a placeholder."""

import re
import struct

import numpy as np
import pytest
from PIL import Image

from rotorlab.vehicles import VEHICLES_DIR, list_vehicles, load_vehicle

FOLDERS = sorted(p for p in VEHICLES_DIR.iterdir() if p.is_dir() and not p.name.startswith(("_", ".")))


def test_every_folder_is_a_vehicle():
    assert [p.name for p in FOLDERS] == list_vehicles()


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: p.name)
def test_folder_has_its_files(folder):
    assert load_vehicle(folder.name).name == folder.name
    readme = (folder / "README.md").read_text(encoding="utf-8")
    assert readme.startswith("# ") and len(readme.splitlines()) > 10
    changelog = (folder / "CHANGELOG.md").read_text(encoding="utf-8")
    assert re.search(r"^## \[\d+\.\d+\.\d+\] - \d{4}-\d{2}-\d{2}$", changelog, re.M), "no released version"
    png = (folder / "vehicle.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", png[16:24])
    assert width >= 320 and height >= 200, (width, height)
    pixels = np.asarray(Image.open(folder / "vehicle.png").convert("RGB")).reshape(-1, 3)
    assert len(np.unique(pixels, axis=0)) > 100, "a flat picture: render it with docs/render_vehicles.py"
