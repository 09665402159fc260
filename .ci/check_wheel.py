"""Build the wheel (``pip wheel --no-deps``) into a temporary folder and check it holds every package of the
source tree (every folder with an ``__init__.py`` below the folders pyproject maps under ``rotorlab``), the
vehicle, scene and spec data files, and the ``.py`` source of every module a build compiles (``rotorlab.compiled``;
the wheel holds the extensions too where a compiler was there). Exit status 1 with the missing names otherwise.

Usage: python .ci/check_wheel.py
"""

import importlib.util
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def source_packages() -> set[str]:
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    out = set()
    for name, folder in mapping.items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            rel = init.parent.relative_to(base).parts
            if not any(p.startswith(".") or p == "__pycache__" for p in rel):
                out.add(".".join((name, *rel)))
    return out


def compiled_modules() -> tuple[str, ...]:
    spec = importlib.util.spec_from_file_location("_rotorlab_compiled", ROOT / "rotorlab" / "compiled.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.MODULES


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", tmp, str(ROOT)], check=True)
        wheel = next(Path(tmp).glob("rotorlab-*.whl"))
        names = zipfile.ZipFile(wheel).namelist()
    in_wheel = {n.rsplit("/", 1)[0].replace("/", ".") for n in names if n.endswith("/__init__.py")}
    missing = sorted(source_packages() - in_wheel)
    data = [n for n in names if n.endswith(".toml")]
    print(f"{wheel.name}: {len(in_wheel)} packages, {len(names)} files, {len(data)} TOML data files")
    if missing:
        print("missing from the wheel: " + ", ".join(missing))
        return 1
    if not any(n.endswith("anteos-p2a2/vehicle.toml") for n in names):
        print("missing from the wheel: the vehicle TOML files")
        return 1
    sources = sorted(m for m in compiled_modules() if m.replace(".", "/") + ".py" not in names)
    if sources:
        print("missing from the wheel: the source of " + ", ".join(sources))
        return 1
    built = [n for n in names if n.endswith((".so", ".pyd"))]
    print(f"compiled modules in the wheel: {len(built)} of {len(compiled_modules())}")
    unrecorded = [n for n in built if n + ".source-sha256" not in names]
    if unrecorded:  # rotorlab.compiled would never import them
        print("missing from the wheel: the source hash of " + ", ".join(unrecorded))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
