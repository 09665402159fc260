"""Hypothesis fuzzing of every user input file (rotorlab issue 15): vehicle, spec and gains TOML mutated from the
shipped files, and logs mutated from a valid one. Whatever the input, the CLI either works (exit 0 or 1) or
exits 2 with an error line; no exception and no traceback escapes. Bounded examples keep it fast.
"""

from __future__ import annotations

import json
import math
import os
import tomllib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

hypothesis = pytest.importorskip("hypothesis")
from helpers import published_tf  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from rotorlab.cli import main  # noqa: E402
from rotorlab.tune import goals  # noqa: E402
from rotorlab.vehicles import VEHICLES_DIR  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
VEHICLE = tomllib.loads((VEHICLES_DIR / "anteos-p2a2" / "vehicle.toml").read_text())
SPEC = tomllib.loads((ROOT / "tune" / "specs" / "anteos-p2a2.toml").read_text())
GAINS = tomllib.loads((VEHICLES_DIR / "anteos-p2a2" / "gains" / "standard.toml").read_text())
# 25 fixed examples per input in the suite; ROTORLAB_FUZZ_EXAMPLES=500 explores further (random seed)
_N = int(os.environ.get("ROTORLAB_FUZZ_EXAMPLES", "25"))
FUZZ = settings(max_examples=_N, deadline=None, derandomize=_N == 25, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


# -- a TOML writer for the tests (the standard library only reads TOML) ------------------------------------------
def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict) -> str:
    lines = [f"{json.dumps(k)} = {_value(v)}" for k, v in doc.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))]

    def table(prefix, t):
        lines.append(f"[{prefix}]")
        subs = []
        for k, v in t.items():
            if isinstance(v, dict) and v and all(isinstance(x, dict) for x in v.values()):
                subs.append((k, v))
            else:
                lines.append(f"{json.dumps(k)} = {_value(v)}")
        for k, v in subs:
            table(f"{prefix}.{json.dumps(k)}", v)

    for k, v in doc.items():
        if isinstance(v, dict):
            table(json.dumps(k), v)
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                lines.append(f"[[{json.dumps(k)}]]")
                lines += [f"{json.dumps(kk)} = {_value(vv)}" for kk, vv in x.items()]
    return "\n".join(lines) + "\n"


def test_toml_writer_round_trips():
    for doc in (VEHICLE, SPEC, GAINS):
        assert tomllib.loads(to_toml(doc)) == doc


# -- mutations ---------------------------------------------------------------------------------------------
scalars = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20), st.booleans(),
    st.text(max_size=8), st.sampled_from([0, 0.0, -1.0, 1e-300, 1e300, "true", "nan"]))
values = st.one_of(scalars, st.lists(scalars, max_size=5), st.dictionaries(st.text(max_size=5), scalars, max_size=2))


def _paths(doc, prefix=()):
    """Every (container, key) pair reachable in ``doc``, tables and arrays of tables included."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc)
    for k, v in items:
        out.append((doc, k))
        if isinstance(v, dict) or (isinstance(v, list) and v and all(isinstance(x, dict) for x in v)):
            out += _paths(v, prefix + (k,))
    return out


@st.composite
def mutated(draw, base: dict):
    doc = json.loads(json.dumps(base))  # deep copy (the shipped files hold only JSON-able values)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:  # everything deleted already
            break
        container, key = draw(st.sampled_from(paths))
        action = draw(st.sampled_from(["replace", "delete", "typo", "add"]))
        if action == "replace":
            container[key] = draw(values)
        elif action == "delete" and isinstance(container, dict):
            del container[key]
        elif action == "typo" and isinstance(container, dict) and isinstance(key, str) and len(key) > 1:
            i = draw(st.integers(0, len(key) - 2))
            container[key[:i] + key[i + 1] + key[i] + key[i + 2:]] = container.pop(key)
        elif action == "add" and isinstance(container.get(key) if isinstance(container, dict) else None, dict):
            container[key][draw(st.text(min_size=1, max_size=6))] = draw(values)
    return doc


def _no_escape(capsys, argv, ok=(0, 1, 2)):
    rc = main([str(a) for a in argv])  # any exception escaping main fails the test with its traceback
    out, err = capsys.readouterr()
    assert rc in ok, (rc, err)
    assert "Traceback" not in out + err
    if rc == 2:
        assert "error:" in err
    return rc


# -- the fuzz tests ----------------------------------------------------------------------------------------
def _run_rest_with(tmp_path, capsys, flag: str, name: str, doc: dict) -> None:
    """``rotorlab run rest`` on the pitch rig with ``doc`` written to ``name`` and passed as ``flag``."""
    p = tmp_path / name
    p.write_text(to_toml(doc))
    _no_escape(capsys, ["run", "rest", "--scene", "pitch-rig", flag, p, "--duration", "0.04",
                        "--out", tmp_path / "r"])


@FUZZ
@given(doc=mutated(VEHICLE))
def test_fuzz_vehicle_toml(tmp_path, capsys, doc):
    _run_rest_with(tmp_path, capsys, "--vehicle", "vehicle.toml", doc)


@FUZZ
@given(doc=mutated(GAINS))
def test_fuzz_gains_toml(tmp_path, capsys, doc):
    _run_rest_with(tmp_path, capsys, "--gains", "g.toml", doc)


@pytest.fixture
def quick_tune(monkeypatch):
    """``rotorlab tune`` with the optimiser replaced by one evaluation of the start gains: the spec's goals are
    all built and evaluated (where a bad number would bite) in a fraction of a second."""
    def once(spec, models, start, **kw):
        return goals.TuneResult(gains=start, report=goals.evaluate(spec, start, models), objective=0.0,
                                history=[None], starts=[0.0], time_s=0.0)

    monkeypatch.setattr(goals, "tune_cascade", once)


@FUZZ
@given(doc=mutated(SPEC))
def test_fuzz_spec_toml(tmp_path, capsys, quick_tune, doc):
    p = tmp_path / "spec.toml"
    p.write_text(to_toml(doc))
    m = tmp_path / "m.json"
    G, delay_s = published_tf("anteos-p2a2", "testbed")
    m.write_text(json.dumps({"num": G.num[0][0].tolist(), "den": G.den[0][0].tolist(), "dt": 0, "delay_s": delay_s}))
    _no_escape(capsys, ["tune", "--model", m, "--spec", p, "--out", tmp_path / "g.toml"])


@FUZZ
@given(n=st.integers(0, 400), scale=st.sampled_from([1.0, 1e-300, 1e300, math.nan, math.inf, -1.0]),
       jitter=st.floats(0, 0.05), units=st.sampled_from([None, b"{}", b"[1]", b"{bad", b"\xff\xfe"]),
       cut=st.one_of(st.none(), st.floats(0.0, 0.99)), constant=st.booleans())
def test_fuzz_logs(tmp_path, capsys, n, scale, jitter, units, cut, constant):
    rng = np.random.default_rng(n)
    u = np.zeros(n) if constant else np.sign(rng.standard_normal(n))
    y = np.convolve(u, 0.1 * 0.9 ** np.arange(30))[:n] if n else np.zeros(0)
    t = np.arange(n) * 0.02 + rng.uniform(0, jitter * 0.02, n)
    md = {b"rotorlab": b"{}"} if units is None else {b"units": units}
    p = tmp_path / "log.parquet"
    pq.write_table(pa.table({"t": t, "u": u * scale, "y": y * scale}).replace_schema_metadata(md), p)
    if cut is not None:
        data = p.read_bytes()
        p.write_bytes(data[: int(len(data) * cut)])
    _no_escape(capsys, ["ident", p, "--method", "pi-moesp", "--input", "u", "--output", "y", "--order", "2",
                        "--horizon", "5", "--out", tmp_path / "m.json"], ok=(0, 2))


# -- issue 26: the fault classes, property by property -------------------------------------------------------
def _numeric_fields(doc, prefix=()):
    """(dotted field, container, key) of every number (or list of numbers) in a parsed vehicle file."""
    out = []
    for k, v in doc.items():
        if isinstance(v, dict) and k not in ("sources", "published"):
            out += _numeric_fields(v, prefix + (k,))
        elif (isinstance(v, (int, float)) and not isinstance(v, bool)) or (
                isinstance(v, list) and v and all(isinstance(x, (int, float)) for x in v)):
            out.append((".".join(prefix + (k,)), doc, k))
    return out


extreme = st.one_of(st.sampled_from([1e300, -1e300, 1e-300, 5e-324, 1e7, 1e-10]),
                    st.integers(10**18, 10**30), st.just(10**400), st.just(-(10**4000)))


@FUZZ
@given(data=st.data())
def test_fuzz_extreme_vehicle_numbers_name_their_field(tmp_path, capsys, data):
    """Huge, tiny and over-long numbers in any field of a vehicle file never reach MuJoCo or overflow: the run
    works or exits 2 naming the file (and the field, unless MuJoCo itself refuses the built model)."""
    doc = json.loads(json.dumps(VEHICLE))
    fields = _numeric_fields(doc)
    name, container, key = data.draw(st.sampled_from(fields))
    value = data.draw(extreme)
    container[key] = [value] * len(container[key]) if isinstance(container[key], list) else value
    p = tmp_path / "vehicle.toml"
    p.write_text(to_toml(doc))
    rc = main([str(a) for a in ["run", "rest", "--scene", "pitch-rig", "--vehicle", p, "--duration", "0.04",
                                "--out", tmp_path / "r"]])
    out, err = capsys.readouterr()
    assert rc in (0, 1, 2) and "Traceback" not in out + err, (rc, err)
    if rc == 2:
        assert str(p) in err, err
        if "MuJoCo could not compile" not in err and "field 'duration'" not in err:
            assert f"'{name}'" in err or "'airframe.mass_kg'" in err, (name, err)


@FUZZ
@given(name=st.text(max_size=80))
def test_fuzz_names_from_files_never_leave_their_folder(name):
    """Whatever the text, a name check_name accepts is one path component inside the folder it is put in."""
    from rotorlab.config import check_name
    from rotorlab.errors import ConfigError

    try:
        ok = check_name(name, "v.toml", "vehicle.name")
    except ConfigError as exc:
        assert "v.toml" in str(exc) and "'vehicle.name'" in str(exc)
        return
    p = Path("runs") / f"rest-{ok}-seed0"
    assert p.parent == Path("runs") and ".." not in p.parts and len(p.parts) == 2 and "\x00" not in ok


json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(), st.integers(-(10**30), 10**30), st.text(max_size=4)),
    lambda children: st.one_of(st.lists(children, max_size=4), st.dictionaries(st.text(max_size=4), children,
                                                                                max_size=3)), max_leaves=12)


@FUZZ
@given(doc=st.fixed_dictionaries({}, optional={"num": json_values, "den": json_values, "dt": json_values,
                                               "delay_s": json_values, "format": json_values, "A": json_values}),
       depth=st.sampled_from([0, 0, 40, 5000]), digits=st.sampled_from([0, 0, 400, 5000]))
def test_fuzz_model_json(tmp_path, doc, depth, digits):
    """Any model JSON (nested, over-long numbers, wrong types): load_model returns a model or raises a
    ConfigError naming the file, nothing else."""
    from rotorlab.errors import ConfigError
    from rotorlab.ident.modelio import load_model

    text = json.dumps(doc)
    if depth:
        text = text[:-1] + (", " if doc else "") + '"num": ' + "[" * depth + "]" * depth + "}"
    if digits:
        text = text[:-1] + (", " if text != "{}" else "") + '"dt": ' + "7" * digits + "}"
    p = tmp_path / "m.json"
    p.write_text(text)
    try:
        load_model(p)
    except ConfigError as exc:
        assert str(p) in str(exc) and len(str(exc)) < 2000


@FUZZ
@given(spelling=st.sampled_from(["same", "dot", "updown", "symlink", "hardlink", "abs"]))
def test_fuzz_any_spelling_of_an_input_is_refused_as_output(tmp_path, spelling):
    from rotorlab import atomic
    from rotorlab.errors import ConfigError

    (tmp_path / "d").mkdir(exist_ok=True)
    src = tmp_path / "d" / "in.json"
    src.write_text("{}")
    out = {"same": src, "dot": tmp_path / "d" / "." / "in.json", "updown": tmp_path / "d" / ".." / "d" / "in.json",
           "abs": src.resolve(), "symlink": tmp_path / "link.json", "hardlink": tmp_path / "hard.json"}[spelling]
    if spelling == "symlink" and not out.is_symlink():
        out.symlink_to(src)
    if spelling == "hardlink" and not out.exists():
        os.link(src, out)
    with pytest.raises(ConfigError, match="the output is the input file"):
        atomic.check_output(out, [src])
    assert src.read_text() == "{}"
