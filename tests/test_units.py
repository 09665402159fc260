"""Time bases and units of user data (issue 26): a time column not in seconds is converted or refused, never
used as seconds; models carry their input/output units and ``rotorlab tune`` refuses or converts a model whose
units are not the spec's. Ground truth: the sample time a log was written with, conversion factors by hand
(180/pi, 100), a plant whose discrete pole is known."""

import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import published_tf
from scipy.signal import lfilter

from rotorlab import units
from rotorlab.cli import main
from rotorlab.errors import ConfigError, DataError
from rotorlab.gains import load_gains
from rotorlab.ident.logs import load_log, write_log
from rotorlab.ident.modelio import load_model, model_io_units
from rotorlab.ident.timebase import time_in_seconds
from rotorlab.lti import freqresp
from rotorlab.tune.cascade import PlantModel
from rotorlab.tune.goals import evaluate
from rotorlab.tune.spec import load_spec, model_in_spec_units, parse_spec, unit_conversion
from rotorlab.vehicles import VEHICLES_DIR

N = 3000


def _plant_io(n=N, seed=1):
    """``y[k+1] = 0.9 y[k] + 0.2 u[k]``: the discrete pole 0.9, which is s = ln(0.9) / dt rad/s at step dt."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-5.0, 5.0], n // 5), 5)
    return u, lfilter([0.0, 0.2], [1.0, -0.9], u) + 0.01 * rng.standard_normal(n)


def _csv(path, t, u, y, tname="t"):
    path.write_text(f"{tname},u,q\n" + "\n".join(f"{a},{b:.17g},{c:.17g}" for a, b, c in zip(t, u, y)))
    return path


# -- time bases ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("unit,per_s", [("ms", 1e3), ("us", 1e6), ("ns", 1e9)])
def test_a_time_column_in_another_unit_is_converted_exactly_when_the_unit_is_given(unit, per_s):
    dt_s = 0.004  # 250 Hz
    raw = np.int64(1_700_000_000) * np.int64(per_s) + np.arange(1000, dtype=np.int64) * np.int64(dt_s * per_s)
    t, used = time_in_seconds(raw, unit)
    assert used == unit and t[0] == 0.0
    np.testing.assert_allclose(np.diff(t), dt_s, rtol=1e-12)  # 64-bit epoch stamps keep their steps


def test_seconds_are_kept_as_they_are():
    t0 = 0.02 * np.arange(100) + 12.5
    t, used = time_in_seconds(t0)
    assert used == "s" and np.array_equal(t, t0)
    t, used = time_in_seconds(t0, "s")
    assert np.array_equal(t, t0)


def test_microseconds_without_a_unit_are_refused_naming_file_column_expected_and_got():
    raw = np.arange(1000) * 4000  # us at 250 Hz: a step of 4000 "s" before the fix
    with pytest.raises(DataError) as e:
        time_in_seconds(raw, source="flight.csv", column="time")
    msg = str(e.value)
    for s in ("flight.csv", "'time'", "expected time stamps in s", "median step of 4000", "us (250 Hz)",
              "--time-unit us"):
        assert s in msg, (s, msg)
    t, used = time_in_seconds(raw, "auto")
    assert used == "us" and np.diff(t)[0] == pytest.approx(0.004, rel=1e-12)


def test_auto_refuses_a_step_that_fits_two_units():
    raw = np.arange(100) * 200.0  # ms at 5 Hz or us at 5 kHz
    with pytest.raises(DataError, match=r"ms \(5 Hz\) or us \(5000 Hz\)"):
        time_in_seconds(raw, "auto")
    assert time_in_seconds(raw, "ms")[0][1] == pytest.approx(0.2)


def test_typed_time_stamps_carry_their_unit_and_a_declared_unit_is_checked(tmp_path):
    dt_s = 0.02
    u, y = _plant_io(500)
    # an Arrow timestamp column: read as 20000 "s" steps before the fix
    p = tmp_path / "ts.parquet"
    pq.write_table(pa.table({"t": pa.array(np.arange(500) * 20_000, pa.timestamp("us")), "u": u, "q": y}), p)
    log = load_log(p)
    assert log.dt == pytest.approx(dt_s, rel=1e-12) and log.time_unit == "us" and log.units["t"] == "s"
    # a units-metadata "s" on microsecond numbers is refused; "us" there is converted
    bad = write_log(tmp_path / "bad.parquet", {"t": np.arange(500) * 20_000.0, "u": u, "q": y})
    with pytest.raises(DataError, match=r"bad.parquet: time column 't': the file declares it in 's'.*us \(50 Hz\)"):
        load_log(bad)
    assert load_log(bad, time_unit="us").dt == pytest.approx(dt_s, rel=1e-12)
    good = write_log(tmp_path / "good.parquet", {"t": np.arange(500) * 20_000.0, "u": u, "q": y}, units={"t": "us"})
    assert load_log(good).dt == pytest.approx(dt_s, rel=1e-12)


def test_ident_on_a_microsecond_csv_refuses_or_identifies_the_right_dt(tmp_path, capsys):
    """Before: dt = 4000 s and a pole at ln(0.9)/4000 = -2.6e-5 rad/s, exit 0."""
    u, y = _plant_io()
    csv = _csv(tmp_path / "us.csv", 1_700_000_000_000_000 + np.arange(N) * 4000, u, y)
    args = ["ident", str(csv), "--method", "pi-moesp", "--input", "u", "--output", "q", "--order", "1",
            "--out", str(tmp_path / "m.json")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "us.csv" in err and "'t'" in err and "--time-unit us" in err and "Traceback" not in err
    assert main(args + ["--time-unit", "us", "--units", "u=%,q=deg/s"]) == 0
    text = capsys.readouterr().out
    assert "dt = 0.004 s" in text and f"s = {math.log(0.9) / 0.004:.4g} rad/s" in text
    sys_, _, meta = load_model(tmp_path / "m.json")
    assert sys_.dt == pytest.approx(0.004) and model_io_units(meta) == ("%", "deg/s")


# -- units -------------------------------------------------------------------------------------------------------

def test_conversion_factors_are_the_hand_computed_ones():
    assert units.factor("rad/s", "deg/s") == pytest.approx(180.0 / math.pi, rel=1e-15)
    assert units.factor("deg/s", "rad/s") == pytest.approx(math.pi / 180.0, rel=1e-15)
    assert units.factor("1", "%") == 100.0 and units.factor("%", "1") == 0.01
    assert units.factor("dps", "deg/s") == 1.0 and units.factor("µs", "s") == 1e-6
    assert units.factor("%", "deg/s") is None and units.factor("m/s", "deg/s") is None
    assert units.factor("m/s", "m/s") == 1.0


def _tf_model(path, G, delay_s, unit_map=None):
    doc = {"num": G.num[0][0].tolist(), "den": G.den[0][0].tolist(), "dt": 0, "delay_s": delay_s}
    if unit_map is not None:
        doc["units"] = unit_map
    path.write_text(json.dumps(doc))
    return path


def test_a_model_in_rad_s_per_normalised_command_is_the_published_one_once_converted():
    """The published test-bed model in deg/s per % is G; in rad/s per normalised command (1 = 100 %) it is
    G (pi/180) 100. Converting back multiplies by 180/pi and 1/100."""
    G, _ = published_tf("anteos-p2a2", "testbed")
    spec = load_spec("anteos-p2a2")
    with pytest.raises(ConfigError) as e:
        unit_conversion(("1", "rad/s"), spec, "rad.json")
    msg = str(e.value)
    assert "rad.json" in msg and "field 'units'" in msg and "model output rad/s, spec deg/s: scale the output by " \
        "57.2958" in msg and "scale the input by 0.01" in msg and "--convert-units" in msg
    k_in, k_out, note = unit_conversion(("1", "rad/s"), spec, convert=True)
    assert (k_in, k_out) == (0.01, pytest.approx(180 / math.pi, rel=1e-15)) and "converted" in note
    G_rad = G * (math.pi / 180.0 * 100.0)
    w = np.logspace(-1, 2, 30)
    np.testing.assert_allclose(freqresp(k_out * G_rad * k_in, w), freqresp(G, w), rtol=1e-12)
    assert unit_conversion(("%", "deg/s"), spec) == (1.0, 1.0, "")
    k_in, k_out, note = unit_conversion((None, None), spec)
    assert (k_in, k_out) == (1.0, 1.0) and "carries no unit for its input and output" in note
    with pytest.raises(ConfigError, match="cannot be converted"):
        unit_conversion(("%", "m/s"), spec, convert=True)


def test_a_spec_states_the_cascades_units_only(tmp_path):
    base = {"cascade": {"dt": 0.02, "tune": ["outer.kp"]}, "goal": [{"type": "poles", "min_damping": 0.1}]}
    assert parse_spec(base).output_unit == "deg/s"
    with pytest.raises(ConfigError, match="output_unit"):
        parse_spec({**base, "cascade": {**base["cascade"], "output_unit": "rad/s"}})


def test_tune_refuses_a_model_in_other_units_and_converts_it_when_asked(tmp_path, capsys):
    G, delay_s = published_tf("anteos-p2a2", "testbed")
    rad = _tf_model(tmp_path / "rad.json", G * (math.pi / 180.0 * 100.0), delay_s, {"input": "1", "output": "rad/s"})
    deg = _tf_model(tmp_path / "deg.json", G, delay_s, {"input": "%", "output": "deg/s"})
    old = _tf_model(tmp_path / "old.json", G, delay_s)
    common = ["--spec", "anteos-p2a2", "--starts", "1", "--max-iter", "2", "--jobs", "1"]
    assert main(["tune", "--model", str(rad), "--out", str(tmp_path / "r.toml")] + common) == 2
    err = capsys.readouterr().err
    assert "rad.json" in err and "scale the output by 57.2958" in err
    for m, extra in ((rad, ["--convert-units"]), (old, [])):
        assert main(["tune", "--model", str(m), "--out", str(tmp_path / f"{m.stem}.toml")] + common + extra) in (0, 1)
        text = capsys.readouterr().out
        assert f"{m.name}: " + ("converted to the spec's units" if extra else "carries no unit") in text
    # the converted model is the published one: every goal of the spec, at the standard gains, the same
    spec = load_spec("anteos-p2a2")
    gains = load_gains(VEHICLES_DIR / "anteos-p2a2" / "gains" / "standard.toml")
    values = {}
    for m in (rad, deg):
        sys_, delay, meta = load_model(m)
        G, _ = model_in_spec_units(sys_, model_io_units(meta), spec, m, convert=True)
        values[m.stem] = [r.value for r in evaluate(spec, gains, [PlantModel(G, delay)])]
    np.testing.assert_allclose(values["rad"], values["deg"], rtol=1e-9)
    assert len(values["deg"]) >= 5
