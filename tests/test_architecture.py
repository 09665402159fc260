"""The package's import graph, read from the source of every module of the installed ``rotorlab``: no import
cycle, and the layering the README states (``ident/`` and ``tune/`` never import ``mujoco`` or
``rotorlab.sim``; ``sim/`` never imports ``ident/`` or ``tune/``). Function-level imports count: a cycle
hidden inside a function still ties two modules together."""

import ast
import importlib.util
import pkgutil
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules() -> dict[str, str]:
    """Every module of the installed package -> its source file. The roots are the packages pyproject maps
    (``rotorlab`` and the top-level folders installed under it); each is walked where it is installed (an
    editable install resolves the mapped folders through its own finder, which ``pkgutil`` does not see). A module
    a build compiled (``rotorlab.compiled``) is read from the ``.py`` beside its extension, the source it was built
    from."""
    roots = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    mods = {}
    for root in roots:
        spec = importlib.util.find_spec(root)
        mods[root] = spec.origin
        for info in pkgutil.walk_packages(spec.submodule_search_locations, root + "."):
            sub = importlib.util.find_spec(info.name)
            if sub is None or not sub.origin:
                continue
            origin = Path(sub.origin)
            if origin.suffix != ".py":
                origin = origin.with_name(info.name.rpartition(".")[2] + ".py")
            if origin.is_file():
                mods[info.name] = str(origin)
    return mods


MODULES = _modules()


def _imports(name: str, path: str) -> set[str]:
    """Absolute names of every module ``name`` imports (any depth in the file). ``from P import x`` is an
    edge to ``P.x`` when that is a module, else to ``P``."""
    tree = ast.parse(open(path, encoding="utf-8").read(), path)
    is_pkg = path.endswith("__init__.py")
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = name.split(".")
                anchor = parts if is_pkg else parts[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            for a in node.names:
                full = f"{base}.{a.name}"
                out.add(full if full in MODULES else base)
    return out


GRAPH = {m: {t for t in _imports(m, p) if t in MODULES and t != m} for m, p in MODULES.items()}
RAW = {m: _imports(m, p) for m, p in MODULES.items()}


def _cycles(graph) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_walk_sees_the_whole_package():
    for m in ("rotorlab.pipeline.runner", "rotorlab.pipeline.stages.report", "rotorlab.sim.linearize",
              "rotorlab.tune.cascade", "rotorlab.ident.subspace", "rotorlab.vehicles", "rotorlab.scenes"):
        assert m in MODULES, m
    assert len(MODULES) > 80


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle():
    assert _cycles(GRAPH) == []


@pytest.mark.parametrize("layer", ["rotorlab.ident", "rotorlab.tune"])
def test_ident_and_tune_import_neither_mujoco_nor_sim(layer):
    bad = {m: sorted(t for t in RAW[m] if t.split(".")[0] == "mujoco" or t.startswith("rotorlab.sim"))
           for m in MODULES if m == layer or m.startswith(layer + ".")}
    assert {m: b for m, b in bad.items() if b} == {}


def test_sim_imports_neither_ident_nor_tune():
    bad = {m: sorted(t for t in RAW[m] if t.startswith(("rotorlab.ident", "rotorlab.tune")))
           for m in MODULES if m.startswith("rotorlab.sim")}
    assert {m: b for m, b in bad.items() if b} == {}


def test_autopilot_laws_are_on_the_ground_floor():
    """The autopilots' laws serve the flight software, identification and tuning alike, so they import none of
    them (nor MuJoCo)."""
    mods = [m for m in MODULES if m == "rotorlab.autopilots" or m.startswith("rotorlab.autopilots.")]
    assert "rotorlab.autopilots.px4" in mods and "rotorlab.autopilots.ardupilot" in mods
    bad = {m: sorted(t for t in RAW[m] if t.split(".")[0] == "mujoco"
                     or t.startswith(("rotorlab.sim", "rotorlab.ident", "rotorlab.tune")))
           for m in mods}
    assert {m: b for m, b in bad.items() if b} == {}
