"""The documentation a newcomer reads first: a short README in the manner of python-control's and RotorPy's, and
documentation pages whose relative links and images all resolve."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
BEGIN = "<!-- readme_numbers: begin"
END = "<!-- readme_numbers: end -->"
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def _links(md: Path):
    """(target, line number) of every relative link or image in a Markdown file, code blocks skipped."""
    fenced = False
    for n, line in enumerate(md.read_text(encoding="utf-8").splitlines(), 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            continue
        for target in LINK.findall(re.sub(r"`[^`]*`", "", line)):
            if not re.match(r"[a-z]+:", target) and not target.startswith("#"):
                yield target.split("#")[0], n


def test_readme_is_short():
    text = README.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; move detail into docs/"
    long = [(n, len(ln)) for n, ln in enumerate(lines, 1) if len(ln) > 120]
    assert not long, f"README.md lines over 120 characters (line, length): {long} (the generated block too: " \
                     "the report's headline wraps at 118)"
    assert BEGIN in text and END in text, "the generated headline block (docs/readme_numbers.py) is missing"


def test_readme_has_a_picture_and_the_quick_start():
    text = README.read_text(encoding="utf-8")
    images = [t for t, _ in _links(README) if t.endswith(".png")]
    assert images and all((ROOT / t).is_file() for t in images), images
    joined = text.replace("\\\n  ", "")  # a shell line continuation: the same command, wrapped
    assert ("python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/rotorlab pipeline --vehicle anteos-p2a2 "
            "--quick --out runs/p2a2") in joined
    assert 'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest -q -n 2' in joined


@pytest.mark.parametrize("md", [README, *sorted(DOCS.glob("*.md"))], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(md):
    broken = []
    for target, n in _links(md):
        path = (md.parent / target).resolve()
        if not path.exists() and not (md.parent / (target + ".rst")).exists():
            broken.append(f"{md.name}:{n}: {target}")
    assert not broken, broken



@pytest.mark.parametrize("pkg", ["ident", "tune"])
def test_api_reference_lists_every_public_name(pkg):
    """docs/api/PKG.rst (autosummary) names every entry of the package's ``__all__``: nothing public goes
    undocumented on the site when a function is added."""
    import importlib

    mod = importlib.import_module(f"rotorlab.{pkg}")
    listed = set(re.findall(r"^   (\S+)$", (DOCS / "api" / f"{pkg}.rst").read_text(encoding="utf-8"), re.M))
    missing = sorted(set(mod.__all__) - listed)
    assert not missing, f"add to docs/api/{pkg}.rst: {missing}"
