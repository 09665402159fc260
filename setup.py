"""Package discovery for setuptools; the project's metadata and options are in pyproject.toml.

The top-level folders install under the rotorlab namespace (``sim/`` -> ``rotorlab.sim``, the mapping
``[tool.setuptools] package-dir``), which setuptools' own ``packages.find`` cannot express: it would install
``sim`` as a top-level package. Every package below each mapped folder (a folder with an ``__init__.py``) is
found here instead, so a new sub-package reaches the wheel without a hand-written list.
"""

import tomllib
from pathlib import Path

from setuptools import find_packages, setup

ROOT = Path(__file__).resolve().parent


def discover(root: Path = ROOT) -> list[str]:
    """Every package of the distribution: each mapped name and the packages found below its folder."""
    package_dir = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    packages = []
    for name, folder in package_dir.items():
        packages += [name] + [f"{name}.{p}" for p in find_packages(str(root / folder))]
    return sorted(packages)


if __name__ == "__main__":
    setup(packages=discover())
