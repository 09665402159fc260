"""Log reading/writing: round trip with units and run info, CSV column maps, and clear errors."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from rotorlab.errors import DataError
from rotorlab.ident.logs import check_identifiable, load_log, write_log
from rotorlab.logformat import META_KEY, UNITS_KEY


def _table(N=500, dt=0.02):
    rng = np.random.default_rng(0)
    return {"t": dt * np.arange(N), "u_lon": rng.standard_normal(N), "q": rng.standard_normal(N)}


def test_parquet_round_trip_keeps_units_and_meta(tmp_path):
    p = write_log(tmp_path / "a.parquet", _table(), units={"u_lon": "%", "q": "deg/s"}, meta={"vehicle": "p2a2", "seed": 3})
    md = pq.read_schema(p).metadata
    assert json.loads(md[UNITS_KEY])["q"] == "deg/s" and json.loads(md[META_KEY])["vehicle"] == "p2a2"
    log = load_log(p)
    assert log.columns == ["u_lon", "q"] and log.dt == pytest.approx(0.02)
    assert log.units == {"t": "s", "u_lon": "%", "q": "deg/s"}
    assert log.meta["seed"] == 3 and log.meta["format_version"] == 1
    np.testing.assert_array_equal(log["q"], _table()["q"])
    u, y = log.to_arrays("u_lon", ["q"])
    assert u.shape == (500, 1) and y.shape == (500, 1)
    a, b = log.split(0.7)
    assert len(a) == 350 and len(b) == 150


def test_csv_with_column_map(tmp_path):
    tab = _table(50)
    f = tmp_path / "x.csv"
    f.write_text("time,u_lon,pitch_rate\n" + "\n".join(f"{a},{b},{c}" for a, b, c in zip(*tab.values())))
    log = load_log(f, column_map={"t": "time", "q": "pitch_rate"}, units={"q": "deg/s"})
    assert log.columns == ["u_lon", "q"] and log.units["q"] == "deg/s"
    np.testing.assert_allclose(log["q"], tab["q"])
    with pytest.raises(DataError, match="column map names column"):
        load_log(f, column_map={"t": "nope"})


def test_non_uniform_time_names_row_and_resample_fixes_it(tmp_path):
    tab = _table(100)
    tab["t"] = tab["t"].copy()
    tab["t"][40:] += 0.005  # one long step before row 40
    p = write_log(tmp_path / "b.parquet", tab)
    with pytest.raises(DataError, match=r"non-uniform.*row 40.*nominal 0\.02"):
        load_log(p)
    log = load_log(p, resample=True)
    assert np.allclose(np.diff(log.t), 0.02) and len(log) == 100
    tab["t"][60:] += 0.1
    with pytest.raises(DataError, match=r"gap in the time stamps at row 60"):
        load_log(write_log(tmp_path / "c.parquet", tab))


def test_nan_and_constant_and_missing_columns(tmp_path):
    tab = _table(100)
    tab["q"] = tab["q"].copy()
    tab["q"][17] = np.nan
    p = write_log(tmp_path / "d.parquet", tab)
    with pytest.raises(DataError, match=r"column 'q'.*row 17 \(t = 0.34 s\)"):
        load_log(p)
    log = load_log(p, columns=["u_lon"])  # the bad column is not needed
    with pytest.raises(DataError, match="no column 'q'"):
        log["q"]
    tab = _table(100)
    tab["u_lon"] = np.ones(100)
    log = load_log(write_log(tmp_path / "e.parquet", tab))
    with pytest.raises(DataError, match="'u_lon' is constant"):
        log.to_arrays("u_lon", "q")
    with pytest.raises(DataError, match="no such log file"):
        load_log(tmp_path / "missing.parquet")


def test_check_identifiable(tmp_path):
    log = load_log(write_log(tmp_path / "f.parquet", _table(200)))
    check_identifiable(log, "u_lon", "q", order=4, horizon=10)
    # published p = 40, SISO: 2p(m + p_out) = 160 Hankel columns, so N >= 160 + 2p - 1 = 239 samples
    with pytest.raises(DataError, match=r"200 samples are too few.*need at least 239 \(4.78 s"):
        check_identifiable(log, "u_lon", "q", order=4, horizon=40)
    with pytest.raises(DataError, match="order 12 needs a future horizon"):
        check_identifiable(log, "u_lon", "q", order=12, horizon=10)
