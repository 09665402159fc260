"""The compiled per-tick modules (:mod:`rotorlab.compiled`, built by ``setup.py`` with Cython) fly the same numbers
as their Python source: seeded runs with PX4's laws, ArduPilot's and the built-in cascade, each flown once in a
process importing the Python modules (``ROTORLAB_PURE_PYTHON=1``) and once in a process importing what the install
holds, give every logged column bit for bit the same. Where the install compiled nothing the two processes run the
same Python, and the comparison is the runs' reproducibility; the laws' own tests (test_autopilots.py, the
controller law computed by hand) run on whichever build is installed, and CI runs them on both
(``.ci/run``). The import rule (an extension only where built from the very source beside it) is checked on a
package made up for the test."""

import hashlib
import importlib.machinery
import json
import os
import re
import subprocess
import sys
import textwrap

import pytest

from rotorlab import compiled

#: (scenario, vehicle, scene, controller, seed, duration_s, options): the autopilots' identification flights (their
#: rate loops excited on every axis in turn, noise on), position hold at rest, and the cascade on a rig step
RUNS = [
    ("autopilot-sysid", "tuhh-quad", "free-flight", "px4:defaults", 3, 7.0,
     {"autopilot": "px4", "excite_s": 2.0, "pause_s": 0.3, "lead_s": 0.3}),
    ("autopilot-sysid", "tuhh-quad", "free-flight", "ardupilot:defaults", 4, 7.0,
     {"autopilot": "ardupilot", "excite_s": 2.0, "pause_s": 0.3, "lead_s": 0.3}),
    ("rest", "tuhh-quad", "free-flight", "px4:defaults", 1, 3.0, {}),
    ("gust", "anteos-p2a2", "free-flight", None, 2, 4.0, {}),
    ("setpoint", "anteos-p2a2", "pitch-rig", None, 5, 4.0, {}),
]

_CHILD = textwrap.dedent("""
    import hashlib, json, sys
    import numpy as np
    from rotorlab import compiled
    from rotorlab.sim.control.autopilot import parse_autopilot
    from rotorlab.sim.runner import run_scenario

    out = {"status": compiled.status(), "runs": []}
    for name, vehicle, scene, controller, seed, duration_s, options in json.loads(sys.argv[1]):
        res = run_scenario(name, vehicle, scene=scene, seed=seed, duration_s=duration_s, options=options,
                           sensor_noise=True, controller=parse_autopilot(controller) if controller else None)
        cols = {}
        for col in res.log.columns:
            a = np.ascontiguousarray(res.log[col], dtype=float)
            cols[col] = [hashlib.sha256(a.tobytes()).hexdigest(), a.size, float(np.nansum(np.abs(a)))]
        out["runs"].append({"stopped": res.stopped, "columns": cols})
    print(json.dumps(out))
""")


def _fly(pure: bool) -> dict:
    env = dict(os.environ)
    env.pop(compiled.PURE_ENV, None)
    if pure:
        env[compiled.PURE_ENV] = "1"
    done = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(RUNS)], env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_compiled_and_python_modules_log_the_same_bits():
    pure, installed = _fly(pure=True), _fly(pure=False)
    assert "compiled" not in pure["status"].values()  # ROTORLAB_PURE_PYTHON, or nothing built
    assert set(installed["status"]) == set(compiled.MODULES)
    for (name, *_), a, b in zip(RUNS, pure["runs"], installed["runs"]):
        assert a["stopped"] is None and b["stopped"] is None, (name, a["stopped"], b["stopped"])
        assert len(a["columns"]) > 20 and a["columns"].keys() == b["columns"].keys(), name
        for col, (digest, n, size) in a["columns"].items():
            assert n > 100, (name, col)
            assert b["columns"][col] == [digest, n, size], (name, col, installed["status"])
    # the runs moved: the excited rate loops and the rig step are not flat lines of zeros
    for (name, *_), run in zip(RUNS, pure["runs"]):
        assert run["columns"]["p"][2] + run["columns"]["q"][2] > 0 and run["columns"]["u_lon"][2] > 0, name


def _fake_package(tmp_path, source: str):
    """A package ``pkg`` with ``mod.py`` and a file where an extension of ``pkg.mod`` would be (never loaded:
    the test asks the finder which file it would import)."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "mod.py").write_text(source)
    ext = pkg / ("mod" + importlib.machinery.EXTENSION_SUFFIXES[0])
    ext.write_bytes(b"not loaded")
    return pkg, ext


def test_an_extension_is_imported_only_where_built_from_the_source_beside_it(tmp_path, monkeypatch):
    pkg, ext = _fake_package(tmp_path, "X = 1\n")
    monkeypatch.delenv(compiled.PURE_ENV, raising=False)
    sidecar = ext.with_name(ext.name + compiled.SOURCE_HASH_SUFFIX)
    spec, why = compiled._choose("pkg.mod", [str(pkg)])
    assert why == "pure: stale build" and spec.origin == str(pkg / "mod.py")  # no record of its source
    sidecar.write_text(hashlib.sha256(b"X = 1\n").hexdigest() + "\n")
    spec, why = compiled._choose("pkg.mod", [str(pkg)])
    assert why == "compiled" and spec.origin == str(ext)
    (pkg / "mod.py").write_text("X = 2\n")  # edited after the build: the Python module runs
    spec, why = compiled._choose("pkg.mod", [str(pkg)])
    assert why == "pure: stale build" and spec.origin == str(pkg / "mod.py")
    (pkg / "mod.py").write_text("X = 1\n")
    monkeypatch.setenv(compiled.PURE_ENV, "1")
    spec, why = compiled._choose("pkg.mod", [str(pkg)])
    assert why == "pure: " + compiled.PURE_ENV and spec.origin == str(pkg / "mod.py")
    monkeypatch.setenv(compiled.PURE_ENV, "0")  # 0: not asked
    assert compiled._choose("pkg.mod", [str(pkg)])[1] == "compiled"
    ext.unlink()
    assert compiled._choose("pkg.mod", [str(pkg)]) == (None, "pure: not built")


def _beside(name: str, suffix: str) -> str:
    """The file of module ``name`` with ``suffix`` (``.py``, ``.pxd``) in its package's folder."""
    parent = __import__(name.rpartition(".")[0], fromlist=["_"])
    return os.path.join(parent.__path__[0], name.rpartition(".")[2] + suffix)


@pytest.mark.parametrize("name", compiled.MODULES)
def test_every_compiled_module_is_a_source_file_of_the_package(name):
    """What the build compiles exists as a ``.py`` (``setup.py`` maps the names through pyproject's package-dir),
    and the module imports from the build the finder chose."""
    parent = __import__(name.rpartition(".")[0], fromlist=["_"])
    spec, why = compiled._choose(name, parent.__path__)
    source = _beside(name, ".py")
    assert os.path.isfile(source)
    mod = sys.modules.get(name) or __import__(name, fromlist=["_"])
    assert mod.__file__ == (source if spec is None or why != "compiled" else spec.origin)


def _pxd_declarations(pxd: str) -> tuple[list, list]:
    """The extension types (``cdef class X``) and module-level ``cpdef`` functions a ``.pxd`` declares."""
    classes = re.findall(r"^cdef class (\w+)", pxd, flags=re.M)
    functions = re.findall(r"^cpdef (?:[\w.]+ )?(\w+)\(", pxd, flags=re.M)
    return classes, functions


_HEAPTYPE = 1 << 9  # Py_TPFLAGS_HEAPTYPE: set for a class statement's class, not for an extension type


_WITH_PXD = [n for n in compiled.MODULES if os.path.isfile(_beside(n, ".pxd"))]


@pytest.mark.parametrize("name", _WITH_PXD)
def test_a_compiled_module_was_built_with_the_pxd_beside_it(name):
    """Cython finds a module's ``.pxd`` by the module's installed name, which for ``sim/`` and ``vehicles/`` is
    not the folder the ``.pxd`` sits in: a build that misses it compiles the module untyped without a word
    (``setup.py`` stages the files). Built with it, the ``.pxd``'s classes are extension types (static types,
    where a Python class is a heap type) and its module-level ``cpdef`` functions are exported in
    ``__pyx_capi__``."""
    mod = __import__(name, fromlist=["_"])
    status = compiled.status()[name]
    if status != "compiled":  # a build that compiled nothing: the .py files are the module
        assert status.startswith("pure: ") and mod.__file__.endswith(".py")
        return
    with open(_beside(name, ".pxd"), encoding="utf-8") as f:
        classes, functions = _pxd_declarations(f.read())
    assert classes or functions, name
    for cls in classes:
        assert not getattr(mod, cls).__flags__ & _HEAPTYPE, f"{name}.{cls} is a Python class: its .pxd was not used"
    for fn in functions:
        assert fn in getattr(mod, "__pyx_capi__", {}), f"{name}.{fn} is not the .pxd's cpdef function"
