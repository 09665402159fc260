"""``rotorlab tune`` end to end on the hand-written model form."""

import json

from helpers import published_tf

from rotorlab.cli import main
from rotorlab.gains import load_gains


def test_cli_tune_writes_gains_and_reports_every_goal(tmp_path, capsys):
    model = tmp_path / "tb.json"
    G, delay_s = published_tf("anteos-p2a2", "testbed")
    model.write_text(json.dumps({"num": G.num[0][0].tolist(), "den": G.den[0][0].tolist(), "dt": 0,
                                 "delay_s": delay_s}))
    out = tmp_path / "g.toml"
    rc = main(["tune", "--model", str(model), "--spec", "anteos-p2a2", "--start", "standard", "--out", str(out),
               "--max-iter", "30"])
    text = capsys.readouterr().out
    assert rc == 0
    for goal in ("crossover theta", "crossover q", "tracking theta_ref->theta", "rejection d_u->theta"):
        assert goal in text
    assert "FAIL" not in text
    g = load_gains(out)["pitch"]
    assert g.inner.ki > 0 and g.outer.ki == 0


def test_cli_tune_bad_inputs(tmp_path, capsys):
    model = tmp_path / "m.json"
    model.write_text(json.dumps({"num": [1.0], "den": [1, 1], "dt": 0, "delay_s": 0.06}))
    assert main(["tune", "--model", str(model), "--spec", "no-such-spec", "--out", str(tmp_path / "o.toml")]) == 2
    assert "valid" in capsys.readouterr().err
    assert main(["tune", "--model", str(model), "--spec", "anteos-p2a2", "--start", "nope",
                 "--out", str(tmp_path / "o.toml")]) == 2
    assert "standard" in capsys.readouterr().err
    assert main(["tune", "--model", str(tmp_path / "missing.json"), "--spec", "anteos-p2a2",
                 "--out", str(tmp_path / "o.toml")]) == 2
