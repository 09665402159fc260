"""Every public function of rotorlab.ident and rotorlab.tune has a numpydoc docstring with Parameters, Returns and
an Examples section, and its examples run and print what they show (doctest).

Public: the functions of each package's ``__all__``, plus ``rotorlab.tune.margins.margins`` and
``rotorlab.tune.montecarlo.montecarlo`` (kept in their modules so the module names are not shadowed).
:data:`UNDOCUMENTED` lists the functions still without a complete docstring: it may only shrink (a function
that gains its sections must leave the list, a new function must not enter it).
"""

import doctest
import importlib
import inspect

import numpy as np
import pytest
from numpydoc.docscrape import FunctionDoc


def _public():
    out = {}
    for pkg in ("ident", "tune"):
        mod = importlib.import_module(f"rotorlab.{pkg}")
        for name in mod.__all__:
            obj = getattr(mod, name)
            if inspect.isfunction(obj):
                out[f"{pkg}.{name}"] = obj
    out["tune.margins.margins"] = importlib.import_module("rotorlab.tune.margins").margins
    out["tune.montecarlo.montecarlo"] = importlib.import_module("rotorlab.tune.montecarlo").montecarlo
    return out


PUBLIC = _public()

#: functions allowed without Parameters, Returns and Examples: none (every public function has them)
UNDOCUMENTED = frozenset()


def _missing_sections(fn) -> list[str]:
    doc = FunctionDoc(fn)
    missing = [s for s in ("Parameters", "Returns", "Examples") if not doc[s]]
    if "Returns" in missing and doc["Yields"]:
        missing.remove("Returns")
    return missing


def test_undocumented_list_only_shrinks():
    incomplete = {name for name, fn in PUBLIC.items() if _missing_sections(fn)}
    new = sorted(incomplete - UNDOCUMENTED)
    assert not new, {n: _missing_sections(PUBLIC[n]) for n in new}
    done = sorted(UNDOCUMENTED - incomplete)
    assert not done, f"complete now, remove from UNDOCUMENTED: {done}"
    assert UNDOCUMENTED <= set(PUBLIC), sorted(UNDOCUMENTED - set(PUBLIC))


@pytest.mark.parametrize("name", sorted(set(PUBLIC) - UNDOCUMENTED))
def test_examples_run(name):
    fn = PUBLIC[name]
    tests = doctest.DocTestFinder(recurse=False).find(fn, name, globs={"np": np})
    assert tests and tests[0].examples, f"{name}: the Examples section has no >>> lines"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for t in tests:
        runner.run(t)
    assert runner.failures == 0, f"{name}: {runner.failures} example(s) failed (output above)"
