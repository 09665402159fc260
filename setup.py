"""Package discovery for setuptools; the project's metadata and options are in pyproject.toml.

The top-level folders install under the rotorlab namespace (``sim/`` -> ``rotorlab.sim``, the mapping
``[tool.setuptools] package-dir``), which setuptools' own ``packages.find`` cannot express: it would install
``sim`` as a top-level package. Every package below each mapped folder (a folder with an ``__init__.py``) is
found here instead, so a new sub-package reaches the wheel without a hand-written list.

The per-tick modules (``rotorlab.compiled.MODULES``) are also compiled from their ``.py`` files by Cython, as
optional extensions: without Cython or a C compiler, or where one module fails to compile, the build warns and
that module installs as Python alone (its ``.py`` is in the wheel either way). ``ROTORLAB_PURE_PYTHON=1`` at build
time compiles nothing. The C flags keep the compiled arithmetic the Python arithmetic: ``-ffp-contract=off`` (no
fused multiply-add, whatever ``-march`` a user's ``CFLAGS`` bring), no ``-ffast-math``.
"""

import concurrent.futures
import functools
import hashlib
import importlib.util
import os
import tomllib
from pathlib import Path

from setuptools import Extension, find_packages, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def discover(root: Path = ROOT) -> list[str]:
    """Every package of the distribution: each mapped name and the packages found below its folder."""
    package_dir = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    packages = []
    for name, folder in package_dir.items():
        packages += [name] + [f"{name}.{p}" for p in find_packages(str(root / folder))]
    return sorted(packages)


@functools.cache
def _compiled_module(root: Path = ROOT):
    """``rotorlab/compiled.py`` loaded from its file (the package is not importable while it is being built),
    once per build process."""
    spec = importlib.util.spec_from_file_location("_rotorlab_compiled", root / "rotorlab" / "compiled.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def extensions(root: Path = ROOT) -> list[Extension]:
    """One extension per module of ``rotorlab.compiled.MODULES``, its source the module's ``.py`` (relative to
    ``root``, through pyproject's package-dir mapping)."""
    package_dir = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    out = []
    for name in _compiled_module(root).MODULES:
        package = max((p for p in package_dir if name.startswith(p + ".")), key=len)
        rel = name[len(package) + 1:].replace(".", "/") + ".py"
        out.append(Extension(name, [f"{package_dir[package]}/{rel}"]))
    return out


def _stage_pxd(sources: dict, root: Path = ROOT) -> str:
    """A folder of the per-tick modules' ``.pxd`` files at their installed names' paths
    (``rotorlab/sim/frames.pxd``), for Cython's include path; returns it. Cython looks a module's ``.pxd`` up by
    the module's full name, and ``sim/frames.pxd`` is not where ``rotorlab.sim.frames`` would be (pyproject's
    package-dir mapping): found nowhere, it would be silently ignored and the module compiled untyped. The
    repository root is on the include path too, for ``rotorlab/`` itself (``cimport rotorlab._libm``).

    A copy is rewritten only when its source changed (Cython retranslates a module whose ``.pxd`` is newer than
    its C file) and removed when its source is gone (a stale copy would still be found and compiled in)."""
    stage = root / "build" / "cython-pxd"
    wanted = {}
    for name, source in sources.items():
        pxd, installed = (root / source).with_suffix(".pxd"), Path(*name.split(".")).with_suffix(".pxd")
        if pxd.is_file() and not (root / installed).is_file():
            wanted[stage / installed] = pxd.read_bytes()
    for old in stage.rglob("*.pxd"):
        if old not in wanted:
            old.unlink()
    for target, text in wanted.items():
        if not target.is_file() or target.read_bytes() != text:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(text)
    return str(stage)


class OptionalBuildExt(build_ext):
    """``build_ext`` that cythonizes the extensions first and lets any of them fail: a module that does not build
    stays Python (a warning says which and why). Beside each extension built it writes the SHA-256 of the source
    it was compiled from (``rotorlab.compiled`` imports an extension only where that matches its ``.py``)."""

    def finalize_options(self):
        # cythonized before setuptools reads the extensions (it records per extension what its later steps use)
        compiled = _compiled_module()
        self._sources = {ext.name: ext.sources[0] for ext in extensions()}  # the .py of each, not its .c
        # once per build: setuptools may make several build_ext commands of one distribution (editable mode)
        if not getattr(self.distribution, "_cythonized", False):
            self.distribution._cythonized = True
            if os.environ.get(compiled.PURE_ENV, "") not in ("", "0"):
                self.warn(f"{compiled.PURE_ENV} is set: the per-tick modules install as Python only")
                self.distribution.ext_modules = []
            elif self.distribution.ext_modules:
                self.distribution.ext_modules = self._cythonize(self.distribution.ext_modules)
        super().finalize_options()

    def _cythonize(self, exts: list) -> list:
        """The extensions translated to C: all at once (one process per core), or, where that fails, one by one,
        so that a module Cython cannot translate installs as Python alone (a warning says which and why)."""
        try:
            from Cython.Build import cythonize
        except ImportError as exc:
            self.warn(f"Cython is not installed ({exc}); the per-tick modules install as Python only")
            return []
        # language_level 3 and no annotation typing: the .py files' annotations are documentation, so a compiled
        # function takes what the Python one takes; C types come from the .pxd files alone
        options = dict(build_dir=os.path.join("build", "cython"), quiet=True,
                       include_path=[str(ROOT), _stage_pxd(self._sources)],
                       compiler_directives={"language_level": 3, "binding": True, "annotation_typing": False})
        try:
            return cythonize(exts, nthreads=os.cpu_count() or 1, **options)
        except Exception:  # noqa: BLE001 - which module failed is found below, one at a time
            pass
        out = []
        for ext in exts:
            try:
                out += cythonize([ext], **options)
            except Exception as exc:  # noqa: BLE001 - a module Cython cannot translate stays Python
                self.warn(f"Cython could not translate {ext.name} ({exc!r}); it installs as Python only")
        return out

    def run(self):
        super().run()
        if self.inplace:  # setuptools built into build_lib and copied the extensions into the source tree
            for ext in self.extensions:
                self._record_source(ext, self.get_ext_fullpath(ext.name))

    def build_extensions(self):
        # one compiler process per core (the compiler runs outside Python: threads suffice)
        with concurrent.futures.ThreadPoolExecutor(os.cpu_count() or 1) as pool:
            ok = list(pool.map(self._build_one, self.extensions))
        built = [ext for ext, done in zip(self.extensions, ok) if done]
        # what setuptools copies into the source tree (an editable install) and lists as outputs: the built ones
        self.extensions = built

    def _build_one(self, ext) -> bool:
        if self.compiler.compiler_type == "unix":
            ext.extra_compile_args = [*ext.extra_compile_args, "-ffp-contract=off", "-g0"]
        try:
            self.build_extension(ext)
        except Exception as exc:  # a compiler missing or failing: this module stays Python
            self.warn(f"{ext.name} was not compiled ({exc}); it installs as Python only")
            return False
        self._record_source(ext, self.get_ext_fullpath(ext.name))
        return True

    def _record_source(self, ext, ext_path: str) -> None:
        digest = hashlib.sha256((ROOT / self._sources[ext.name]).read_bytes()).hexdigest()
        Path(ext_path + _compiled_module().SOURCE_HASH_SUFFIX).write_text(digest + "\n", encoding="ascii")


if __name__ == "__main__":
    setup(packages=discover(), ext_modules=extensions(), cmdclass={"build_ext": OptionalBuildExt})
