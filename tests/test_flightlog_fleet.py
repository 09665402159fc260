"""A fleet of flight logs (a folder) through the project's executor: one model folder per log, the fleet summary
(CSV and Markdown), a bad log is a row with its error, and a local Dask cluster gives the numbers this process
gives. The logs are written by the project (tests/flightlog_sim.py)."""

import csv

import pytest
from flightlog_sim import ARDUPILOT_UNFILTERED, dataflash_messages, fly, px4_params, px4_topics

from rotorlab.autopilots import ardupilot
from rotorlab.cli import main
from rotorlab.executor import get_executor
from rotorlab.ident.flightlogs.fleet import COLUMNS, find_logs, identify_fleet
from rotorlab.ident.flightlogs.writers import write_dataflash, write_ulog


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    for seed in (1, 2):
        f = fly(seed=seed, excite_s=6.0)
        write_ulog(d / f"quad{seed}.ulg", px4_topics(f), px4_params(), {"ver_sw_release": 0x010E0000})
    write_dataflash(d / "copter.bin", dataflash_messages(fly(seed=3, excite_s=6.0)), {"ATC_RAT_RLL_P": 0.15, **ARDUPILOT_UNFILTERED})
    write_dataflash(d / "copter2.bin", dataflash_messages(fly(seed=4, excite_s=6.0)),
                    {**ardupilot.TABLE.defaults(), **ARDUPILOT_UNFILTERED})
    (d / "broken.ulg").write_bytes(b"not a ulog")
    (d / "notes.txt").write_text("not a log")
    return d


def _numbers(rows):
    return [(r["log"].rsplit("/", 1)[-1], r["axis"], r["kind"], r["method"], r["vaf_holdout_pct"], bool(r["error"]))
            for r in rows]


def test_fleet_writes_one_folder_per_log_and_the_summary(fleet, tmp_path):
    assert [p.name for p in find_logs(fleet)] == ["broken.ulg", "copter.bin", "copter2.bin", "quad1.ulg",
                                                  "quad2.ulg"]
    res = identify_fleet(fleet, tmp_path / "out", axes=["roll"])
    failed = {r["log"].rsplit("/", 1)[-1]: r["error"] for r in res.failed}
    assert set(failed) == {"broken.ulg", "copter.bin"}
    assert "parameter ATC_RAT_RLL_I is not in the log" in failed["copter.bin"]
    ok = [r for r in res.rows if not r["error"]]
    assert {r["log"].rsplit("/", 1)[-1] for r in ok} == {"copter2.bin", "quad1.ulg", "quad2.ulg"}
    for r in ok:
        assert (tmp_path / "out").joinpath(r["model_file"]).is_file()
        if r["kind"] == "plant-indirect" and r["format"] == "ulog":
            assert r["vaf_holdout_pct"] > 90  # the simulated loop with its known controller
    with open(tmp_path / "out" / "fleet.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert tuple(table[0]) == COLUMNS and len(table) == len(res.rows)
    md = (tmp_path / "out" / "fleet.md").read_text()
    assert md.count("\n") == len(res.rows) + 2 and "broken.ulg" in md


def test_local_dask_cluster_gives_the_same_numbers(fleet, tmp_path):
    pytest.importorskip("dask.distributed")
    here = identify_fleet(fleet, tmp_path / "here", axes=["roll"])
    with get_executor("dask", max_workers=2) as ex:
        on_dask = identify_fleet(fleet, tmp_path / "dask", axes=["roll"], executor=ex)
    a, b = _numbers(here.rows), _numbers(on_dask.rows)
    assert [x[:4] + x[5:] for x in a] == [x[:4] + x[5:] for x in b]
    for x, y in zip(a, b):
        assert x[4] == pytest.approx(y[4], rel=1e-9, abs=1e-9) if x[4] != "" else y[4] == ""


def test_cli_fleet(fleet, tmp_path, capsys):
    rc = main(["ident", str(fleet), "--fleet", "--axis", "roll", "--executor", "serial", "--out",
               str(tmp_path / "m")])
    assert rc == 0
    out = capsys.readouterr().out
    assert "5 logs on serial, 2 not identified" in out
    assert (tmp_path / "m" / "fleet.csv").is_file() and (tmp_path / "m" / "quad1_ulg" / "roll.json").is_file()
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["ident", str(empty), "--fleet", "--out", str(tmp_path / "n")]) == 2
    assert "no flight log in the folder" in capsys.readouterr().err
