"""The identification-method table (rotorlab.ident.methods.METHODS), walked entry by entry: every method
recovers the published P2-A2 test-bed model from data simulated with it (ground truth), and the CLI and
the pipeline use exactly this table."""

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.cli import main
from rotorlab.ident.greybox import simulate_greybox
from rotorlab.ident.methods import METHODS, get_method
from rotorlab.ident.structures import rate_tf_structure
from rotorlab.lti import c2d_zoh, freqresp
from rotorlab.pipeline.stages import identify

PUBLISHED = published_tf("anteos-p2a2", "testbed")[0]  # P2-A2 test-bed, doc 000, delay 0.06 s
DT, DELAY = 0.02, 3
# settings per method; a method added to the table without an entry here fails test_every_method_is_tested
SETTINGS = {
    "pi-moesp": dict(order=2, horizon=20),
    "pbsid": dict(order=2, past=20, future=10),
    "lms-kung": dict(order=2, taps=80),
    # equation error: consistent under output noise only as the order grows (order 2 misses by 60 %)
    "arx": dict(order=8),
    "oe-greybox": dict(structure=rate_tf_structure(), restarts=0, rng=0),
    "hinf-match": dict(structure=rate_tf_structure(delay_s=DELAY * DT), order=2, horizon=20, restarts=0, rng=0),
}


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(0)
    u = np.repeat(rng.choice([-9.0, 9.0], 600), 5)
    y = simulate_greybox(rate_tf_structure(), u, DT)[:, 0]
    return u, y + 0.02 * y.std() * rng.standard_normal(u.size)


def test_every_method_is_tested():
    assert set(SETTINGS) == set(METHODS)


@pytest.mark.parametrize("name", sorted(METHODS))
def test_method_recovers_the_published_model(record, name):
    u, y = record
    m = get_method(name)
    res = m.fit(u, y, dt=DT, delay=DELAY, **SETTINGS[name])
    w = np.logspace(-1, 1.3, 30)  # up to 20 rad/s, where the PRBS has energy
    truth = PUBLISHED if m.greybox else c2d_zoh(ct.ss(PUBLISHED), DT)
    g, g0 = freqresp(res.sys, w)[:, 0, 0], freqresp(truth, w)[:, 0, 0]
    assert np.max(np.abs(g - g0) / np.abs(g0)) < 0.1, name


def test_cli_names_the_table_on_an_unknown_method(tmp_path, capsys):
    rc = main(["ident", str(tmp_path / "x.parquet"), "--method", "moesp", "--input", "u", "--output", "q",
               "--out", str(tmp_path / "m.json")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "unknown identification method 'moesp'; valid: " + ", ".join(sorted(METHODS)) in err


def test_the_pipeline_identifies_with_the_table():
    assert set(identify.OPEN_LOOP_METHODS) <= set(METHODS)
