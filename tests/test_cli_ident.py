"""``rotorlab ident`` end to end on a synthetic Parquet log, and the model JSON it writes and ``tune`` reads."""

import json

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.cli import main
from rotorlab.errors import ConfigError
from rotorlab.ident.greybox import simulate_greybox
from rotorlab.ident.logs import write_log
from rotorlab.ident.model import IdentifiedModel
from rotorlab.ident.modelio import load_model, save_model
from rotorlab.ident.structures import rate_tf_structure
from rotorlab.lti import c2d_zoh, freqresp

PUBLISHED, PUBLISHED_DELAY_S = published_tf("anteos-p2a2", "testbed")  # P2-A2 test-bed, doc 000


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    rng = np.random.default_rng(0)
    dt, N = 0.02, 3000
    u = np.repeat(rng.choice([-9.0, 9.0], N // 5), 5)
    y = simulate_greybox(rate_tf_structure(), u, dt)[:, 0]  # published model with its 0.06 s delay
    y = y + 0.05 * y.std() * rng.standard_normal(N)
    p = tmp_path_factory.mktemp("logs") / "pitch.parquet"
    return write_log(p, {"t": dt * np.arange(N), "u_lon": u, "q": y}, units={"u_lon": "%", "q": "deg/s"})


@pytest.mark.parametrize("method", ["pbsid", "oe-greybox"])
def test_ident_cli_writes_a_model_that_matches_the_truth(log_path, tmp_path, capsys, method):
    out = tmp_path / "m.json"
    extra = ["--past", "30", "--future", "10"] if method == "pbsid" else []
    rc = main(["ident", str(log_path), "--method", method, "--input", "u_lon", "--output", "q", "--order", "2",
               "--delay", "auto", "--cv-split", "0.7", "--out", str(out)] + extra)
    assert rc == 0
    text = capsys.readouterr().out
    assert "estimated delay: 3 samples" in text and "VAF on cross-validation data" in text
    sys, delay_s, meta = load_model(out)
    assert delay_s == pytest.approx(0.06)
    assert meta["input"] == ["u_lon"] and meta["units"] == {"u_lon": "%", "q": "deg/s"}
    assert meta["vaf"][0] > 98.0
    w = np.logspace(-1, 1.3, 30)  # up to 20 rad/s, where the PRBS has energy
    truth = c2d_zoh(ct.ss(PUBLISHED), sys.dt) if sys.dt else PUBLISHED  # pbsid: discrete, oe: continuous
    g, g0 = freqresp(sys, w)[:, 0, 0], freqresp(truth, w)[:, 0, 0]
    assert np.max(np.abs(g - g0) / np.abs(g0)) < 0.05


def test_ident_cli_user_errors_exit_2(log_path, tmp_path, capsys):
    rc = main(["ident", str(log_path), "--method", "pbsid", "--input", "u_lon", "--output", "nope",
               "--out", str(tmp_path / "m.json")])
    assert rc == 2
    assert "no column(s) ['nope']" in capsys.readouterr().err


def test_model_json_round_trip_and_transfer_function_form(tmp_path):
    sysd = c2d_zoh(ct.ss(PUBLISHED), 0.02)
    m = IdentifiedModel(sys=sysd, delay=3, method="pbsid", settings={"order": 2})
    p = save_model(tmp_path / "a.json", m, vaf=[91.5], input=["u_lon"], output=["q"])
    doc = json.loads(p.read_text())
    assert doc["format"] == "rotorlab-model" and doc["delay_samples"] == 3 and doc["dt"] == 0.02
    sys, delay_s, meta = load_model(p)
    assert delay_s == pytest.approx(0.06) and sys.dt == 0.02 and meta["settings"] == {"order": 2}
    np.testing.assert_allclose(sys.A, sysd.A)
    tf = tmp_path / "tf.json"
    num, den = PUBLISHED.num[0][0], PUBLISHED.den[0][0]
    tf.write_text(json.dumps({"num": num.tolist(), "den": den.tolist(), "dt": 0, "delay_s": PUBLISHED_DELAY_S}))
    sys, delay_s, _ = load_model(tf)
    assert sys.dt == 0 and delay_s == PUBLISHED_DELAY_S
    assert ct.dcgain(sys) == pytest.approx(num[-1] / den[-1])


@pytest.mark.parametrize("doc, field", [
    ({"num": [1, 2, 3], "den": [1, 2]}, "num"),
    ({"num": [1], "den": [0, 1]}, "den"),
    ({"num": [1], "den": [1, 1], "dt": -1}, "dt"),
    ({"format": "other"}, "format"),
    ({"format": "rotorlab-model", "version": 1, "A": [[0.5]], "B": [[1, 2]], "C": [[1, 0]], "D": [[0]], "dt": 0.1}, "C"),
    ({"num": [1], "den": [1, 0.5], "dt": 0.02, "delay_s": 0.05}, "delay_s"),
])
def test_model_json_errors_name_file_and_field(tmp_path, doc, field):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match=rf"bad\.json: field '{field}'"):
        load_model(p)
