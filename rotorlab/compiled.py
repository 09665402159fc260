"""The per-tick modules compiled by Cython from their own source, and the import rule that keeps them honest.

The modules in :data:`MODULES` (the autopilot laws and the flight-software tick path) are written once, in plain
Python; ``setup.py`` compiles those same ``.py`` files with Cython when a C compiler is there (the ``.pxd`` file
beside a module, where there is one, declares its per-tick locals as C doubles without changing the ``.py``). A
build without a compiler, or one where compiling fails, installs and runs the ``.py`` files alone. The compiled
module does the same IEEE double operations in the same order as the Python one, so a run gives the same numbers
bit for bit on either (``tests/test_compiled.py``); it only costs less time a tick
(``benchmarks/bench_autopilots.py``).

Importing ``rotorlab`` puts a finder first on ``sys.meta_path`` that, for a module of :data:`MODULES`, takes the
compiled extension only when it was built from the very source beside it (the build records the source's SHA-256
next to the extension); otherwise, as when the environment variable ``ROTORLAB_PURE_PYTHON`` is set to a non-empty
value other than ``0``, it imports the ``.py``. An edited module of an editable install is so never shadowed by an
extension built from its older text: it runs as Python until the next ``pip install -e .``.

Stdlib only: ``setup.py`` reads :data:`MODULES` from this file before anything is installed.

Examples
--------
>>> from rotorlab import compiled
>>> sorted(compiled.status())[0]
'rotorlab.autopilots.ardupilot'
>>> set(compiled.status().values()) <= {"compiled", "pure: not built", "pure: stale build", "pure: " + compiled.PURE_ENV}
True
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys

__all__ = ["MODULES", "PURE_ENV", "SOURCE_HASH_SUFFIX", "pure_python", "status", "install", "source_sha256"]

#: the modules a build compiles: what one control tick of the twin runs (the profile of
#: ``benchmarks/bench_autopilots.py``'s runs), by installed name
MODULES = (
    "rotorlab.autopilots.ardupilot",
    "rotorlab.autopilots.px4",
    "rotorlab.sim.control.autopilot",
    "rotorlab.sim.control.flight_software",
    "rotorlab.sim.control.mixer",
    "rotorlab.sim.control.pid",
    "rotorlab.sim.control.position",
    "rotorlab.sim.frames",
    "rotorlab.sim.log",
    "rotorlab.sim.runner",
    "rotorlab.sim.sensors.base",
    "rotorlab.sim.sensors.imu_accelerometer",
    "rotorlab.sim.sensors.imu_attitude",
    "rotorlab.sim.sensors.imu_gyro",
    "rotorlab.sim.simulator",
    "rotorlab.vehicles.spec",
)
#: set (not empty, not ``0``) at build time: compile nothing; at run time: import every module from its ``.py``
PURE_ENV = "ROTORLAB_PURE_PYTHON"
#: the file the build writes beside each extension: the SHA-256 (hex) of the ``.py`` it was compiled from
SOURCE_HASH_SUFFIX = ".source-sha256"

_MODULE_SET = frozenset(MODULES)


def pure_python() -> bool:
    """Whether :data:`PURE_ENV` asks for the Python modules."""
    return os.environ.get(PURE_ENV, "") not in ("", "0")


def source_sha256(path: str) -> str:
    """SHA-256 (hex) of a file's bytes."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def _choose(fullname: str, path) -> tuple[importlib.machinery.ModuleSpec | None, str]:
    """The spec to import ``fullname`` (a module of :data:`MODULES`) from and why: the extension where it was built
    from the ``.py`` beside it, else the ``.py``; None where the path machinery finds no extension (it then imports
    the module as ever)."""
    spec = importlib.machinery.PathFinder.find_spec(fullname, path)
    if spec is None or not isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
        return None, "pure: not built"
    source = os.path.join(os.path.dirname(spec.origin), fullname.rpartition(".")[2] + ".py")
    if not os.path.isfile(source):  # an install without the sources: the extension is all there is
        return spec, "compiled"
    if pure_python():
        why = "pure: " + PURE_ENV
    else:
        try:
            with open(spec.origin + SOURCE_HASH_SUFFIX, encoding="ascii") as f:
                built_from = f.read().strip()
        except OSError:
            built_from = None
        if built_from == source_sha256(source):
            return spec, "compiled"
        why = "pure: stale build"
    return importlib.util.spec_from_file_location(fullname, source), why


class _Finder(importlib.abc.MetaPathFinder):
    """First on ``sys.meta_path``: the modules of :data:`MODULES` by :func:`_choose`, nothing else."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in _MODULE_SET:
            return None
        return _choose(fullname, path)[0]


def install() -> None:
    """Put the finder first on ``sys.meta_path`` (once; ``rotorlab/__init__.py`` calls it)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


def status() -> dict[str, str]:
    """Module name -> ``"compiled"`` or why it runs as Python (``"pure: not built"``, ``"pure: stale build"``,
    ``"pure: ROTORLAB_PURE_PYTHON"``): the choice an import makes now (the finder's rule)."""
    out = {}
    for name in MODULES:
        parent = importlib.import_module(name.rpartition(".")[0])
        out[name] = _choose(name, parent.__path__)[1]
    return out
