"""What a user of the CLI reads: short run summaries with units and a --json twin, Monte Carlo statistics,
complete --help, scenario options, the viewer on a machine without a display, error hints a CLI user can act
on, and the model ident prints."""

import json
import re
import sys

import numpy as np
import pytest
from helpers import published_tf
from scipy.signal import lfilter

import rotorlab.commands.view as view
import rotorlab.plotting as plotting
from rotorlab.cli import COMMANDS, build_parser, main
from rotorlab.errors import ConfigError
from rotorlab.logformat import read_parquet
from rotorlab.sim.rerun_log import record_run
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.scenarios.gust import DEFAULTS


def _lines(text):
    return [ln for ln in text.splitlines()]


def test_run_summary_is_short_with_units_and_json_has_everything(tmp_path, capsys):
    out = tmp_path / "sp"
    rc = main(["run", "setpoint", "--out", str(out), "--option", "steps_deg=[2, -2]", "--duration", "12"])
    assert rc == 0
    text = capsys.readouterr().out
    lines = _lines(text)
    assert len(lines) <= 40 and max(map(len, lines)) <= 160, text
    assert "np.float64" not in text and "None" not in text and "{" not in text
    # real-time factor of the closed loop alone, model build reported apart
    assert re.search(r"[0-9.]+x real time \(model build [0-9.]+ s", text)
    run_json = json.loads((out / "run.json").read_text())
    steps = run_json["metrics"]["steps"]
    rise = np.mean([s["rise_time_s"] for s in steps if s["rise_time_s"] is not None])
    # the key metrics lead, each with its unit, and equal the numbers in run.json
    assert lines[3].split()[:3] == ["rise", "time", "10-90"] and lines[3].endswith(f"{rise:.4g} s")
    assert any(ln.strip().startswith("overshoot") and ln.endswith(" %") for ln in lines)
    assert any(ln.strip().startswith("settling time") and ln.endswith(" s") for ln in lines)
    assert any(ln.strip().startswith("steady-state error") and ln.endswith(" deg") for ln in lines)
    assert sum(1 for ln in lines if re.match(r"\s+-?[0-9.]+\s+-?[0-9.]+\s+[0-9.]+\s+[0-9.]+", ln)) == len(steps)

    rc = main(["run", "setpoint", "--out", str(out), "--option", "steps_deg=[2, -2]", "--duration", "12", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0 and doc["metrics"] == run_json["metrics"]
    assert doc["timing_s"]["sim_s"] > 0 and doc["real_time_factor"] > 0 and doc["out"] == str(out)


def test_montecarlo_prints_statistics_and_takes_spreads(tmp_path, capsys):
    out = tmp_path / "mc"
    rc = main(["montecarlo", "gust", "--n", "3", "--vary", "mass=0.2,delay", "--executor", "serial",
               "--duration", "4", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    assert s["vary"] == {"mass": 0.2, "delay": 0.02}
    peak = s["metrics"]["pitch.disturbance.peak_deviation"]
    line = next(ln for ln in _lines(text) if "pitch peak deviation [deg]" in ln)
    assert line.split()[-5:] == [f"{peak[k]:.4g}" for k in ("mean", "std", "p05", "p50", "p95")]
    assert "mass 0.2 relative" in text
    # the drawn parameters carry their units in the batch table (metric columns carry theirs in their names)
    _, units, _ = read_parquet(out / "batch-0000.parquet")
    assert {"sample": "1", "mass_factor": "1", "delay_s": "s", "wind_speed_mps": "m/s"}.items() <= units.items()
    assert main(["montecarlo", "gust", "--vary", "mass=2"]) == 2
    assert "expected a spread >= 0 and < 1" in capsys.readouterr().err


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return action.choices


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_help_is_complete(name):
    p = _subparsers()[name]
    text = p.format_help()
    assert "``" not in text and "`" not in text, text
    desc = p.description or ""
    assert desc and desc.rstrip().endswith((".", ")")), f"{name}: description cut mid-sentence: {desc!r}"
    for a in p._actions:
        if a.option_strings and a.help and a.help != "==SUPPRESS==" and a.dest != "help":
            shown = p._get_formatter()._get_help_string(a)
            has_default = a.default not in (None, False, [])
            assert not has_default or "default" in shown, f"{name} {a.option_strings}: default not shown"
        if not a.option_strings and a.dest != "help":
            assert a.help, f"{name} {a.dest}: positional argument without help"
        if a.option_strings and a.dest != "help":
            assert a.help, f"{name} {a.option_strings}: option without help"


def test_list_scenario_shows_options_and_defaults(capsys):
    assert main(["list", "--scenario", "gust"]) == 0
    text = capsys.readouterr().out

    for k in DEFAULTS:
        line = next(ln for ln in _lines(text) if ln.strip().startswith(k))
        assert "default" in line and len(line.split("default", 1)[1].split()) >= 2  # a value and a meaning
    assert main(["list", "--scenario", "gust", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {k: v["default"] for k, v in doc["options"].items()} == DEFAULTS
    assert main(["list", "--scenario", "nope"]) == 2


def test_view_exits_0_without_a_display_and_finds_pipeline_recordings(tmp_path, capsys, monkeypatch):
    for k in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(k, raising=False)
    # as `.venv/bin/rotorlab view` runs without the venv activated: the viewer beside the interpreter, not on PATH
    venv_bin = tmp_path / "venv" / "bin"
    venv_bin.mkdir(parents=True)
    (venv_bin / "rerun").write_text("#!/bin/sh\nexit 0\n")
    (venv_bin / "rerun").chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(venv_bin / "python"))
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    assert view.find_viewer() == str(venv_bin / "rerun")
    res = run_scenario("rest", scene="pitch-rig", duration_s=0.2)
    rec = tmp_path / "pl" / "report" / "recordings"
    for name in ("gust__standard", "setpoint__tuned"):
        record_run(res.log, rec / f"{name}.rrd", info=res.info)
    capsys.readouterr()
    assert main(["view", str(tmp_path / "pl")]) == 0
    text = capsys.readouterr().out
    assert "no display" in text and "--web" in text and str(venv_bin / "rerun") in text
    assert "gust__standard.rrd" in text and "setpoint__tuned.rrd" in text
    assert main(["view", str(tmp_path / "pl"), "--web", "--print"]) == 0
    cmd = capsys.readouterr().out
    assert "--serve-web" in cmd and cmd.strip().endswith("setpoint__tuned.rrd")
    assert main(["view", str(tmp_path / "empty-dir-that-is-missing")]) == 2


def test_ident_hints_name_cli_flags_and_the_flags_work(tmp_path, capsys):

    rng = np.random.default_rng(1)
    n = 2000
    t = 0.02 * np.arange(n)
    u = np.repeat(rng.choice([-5.0, 5.0], n // 5), 5)

    y = lfilter([0.0, 0.2], [1.0, -0.9], u)  # y[k+1] = 0.9 y[k] + 0.2 u[k]
    t_uneven = t.copy()
    t_uneven[1000:] += 0.0005  # one irregular step (2.5 % of dt)
    csv = tmp_path / "log.csv"
    csv.write_text("time,cmd,rate\n" + "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t_uneven, u, y)))
    args = ["ident", str(csv), "--method", "pbsid", "--input", "u", "--output", "q", "--order", "1",
            "--out", str(tmp_path / "m.json")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--column-map t=" in err and "column_map={" not in err.split("in Python")[0]
    assert main(args + ["--column-map", "t=time,u=cmd", "--column-map", "q=rate"]) == 2
    err = capsys.readouterr().err
    assert "--resample" in err and "resample=True" not in err.split("in Python")[0]
    assert main(args + ["--column-map", "t=time,u=cmd", "--column-map", "q=rate", "--resample"]) == 0
    text = capsys.readouterr().out
    # the model as an engineer reads it: the discrete pole 0.9 is s = ln(0.9)/0.02 = -5.27 rad/s, the DC gain
    # 0.2/(1-0.9) = 2
    assert "dt = 0.02 s" in text and "order 1" in text
    pole = next(ln for ln in _lines(text) if ln.strip().startswith("pole"))
    s_pole = float(re.search(r"s = (-?[0-9.]+) rad/s", pole).group(1))
    assert s_pole == pytest.approx(np.log(0.9) / 0.02, rel=0.02)
    dc = float(re.search(r"DC gain u -> q: (-?[0-9.]+)", text).group(1))
    assert dc == pytest.approx(2.0, rel=0.03)
    doc = json.loads((tmp_path / "m.json").read_text())
    assert doc["dt"] == 0.02  # not 0.019999999999988916


def test_errors_print_numbers_not_numpy_reprs():
    assert "np.float64" not in str(ConfigError(field="x", expected="y", got=np.float64(1.0)))


@pytest.fixture
def captured_figures(monkeypatch):
    """Every figure rotorlab.plotting saves, with its axes' labels, kept for inspection (and still written)."""
    figs = []
    real_save = plotting.save

    def save(fig, path):
        figs.append({"path": path, "width_px": fig.get_size_inches()[0] * plotting.DPI,
                     "axes": [{"x": ax.get_xlabel(), "y": ax.get_ylabel(), "grid": ax.xaxis._major_tick_kw.get("gridOn"),
                               "legend": [t.get_text() for t in (ax.get_legend().get_texts() if ax.get_legend() else [])],
                               "lines": [ln.get_label() for ln in ax.get_lines()],
                               "vlines_x": [ln.get_xdata()[0] for ln in ax.get_lines() if ln.get_linestyle() == ":"]}
                              for ax in fig.axes]})
        return real_save(fig, path)

    monkeypatch.setattr(plotting, "save", save)
    return figs


def _check_labelled(fig):
    assert fig["width_px"] >= 1000
    for ax in fig["axes"]:
        assert re.search(r"\[[^\]]+\]$", ax["y"]), f"y label without a unit: {ax['y']!r}"
        assert ax["grid"], "axes without a grid"
    assert re.search(r"\[[^\]]+\]$", fig["axes"][-1]["x"])


def test_plot_compare_and_bode_write_labelled_pngs(tmp_path, capsys, captured_figures):
    a, b = tmp_path / "std", tmp_path / "opt"
    for out, gains in ((a, "standard"), (b, "optimal-testbed")):
        assert main(["run", "setpoint", "--gains", gains, "--out", str(out), "--option", "steps_deg=[2]",
                     "--duration", "9"]) == 0
    assert main(["plot", str(a)]) == 0
    assert (a / "plot.png").stat().st_size > 10_000
    fig = captured_figures[-1]
    _check_labelled(fig)
    assert [ax["y"] for ax in fig["axes"]] == ["theta [deg]", "q [deg/s]", "u_lon [%]"]  # the rig's axis only
    assert "theta_ref" in fig["axes"][0]["lines"]

    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "cmp.png")]) == 0
    text = capsys.readouterr().out
    _check_labelled(captured_figures[-1])
    ra = json.loads((a / "run.json").read_text())["metrics"]["steps"]
    rb = json.loads((b / "run.json").read_text())["metrics"]["steps"]
    rise = [np.mean([s["rise_time_s"] for s in r if s["rise_time_s"] is not None]) for r in (ra, rb)]
    line = next(ln for ln in _lines(text) if ln.startswith("rise time"))
    assert line.split()[-4:] == [f"{rise[0]:.4g}", f"{rise[1]:.4g}", f"{100 * (rise[1] - rise[0]) / rise[0]:+.1f}", "%"]

    mj = tmp_path / "pub.json"
    G, delay_s = published_tf("anteos-p2a2", "testbed")
    num, den = G.num[0][0], G.den[0][0]
    mj.write_text(json.dumps({"num": num.tolist(), "den": den.tolist(), "dt": 0, "delay_s": delay_s,
                              "input": ["u_lon"], "output": ["q"], "units": {"u_lon": "%", "q": "deg/s"}}))
    assert main(["bode", str(mj), "--out", str(tmp_path / "bode.png")]) == 0
    text = capsys.readouterr().out
    fig = captured_figures[-1]
    _check_labelled(fig)
    assert fig["axes"][0]["y"] == "magnitude [dB re 1 (deg/s)/(%)]" and fig["axes"][1]["x"] == "frequency [rad/s]"
    # the published model's poles (-2.79 +/- 3.68j rad/s), zero (-2.906 rad/s) and DC gain
    p = max(np.roots(den), key=lambda s: s.imag)
    assert f"s = {p.real:.4g} +/- {p.imag:.4g}j rad/s" in text and f"s = {-num[1] / num[0]:.4g} rad/s" in text
    assert f"DC gain u_lon -> q: {num[-1] / den[-1]:.4g} (deg/s)/(%)" in text
    assert main(["plot", str(a), "--signals", "nope"]) == 2


def test_plot_marks_the_in_flight_gain_switch(tmp_path, captured_figures):
    out = tmp_path / "hover"
    assert main(["run", "hover", "--gains", "standard", "--duration", "4", "--option", "switch_s=2.0",
                 "--option", 'switch_to="optimal-flight"', "--option", "turbulence=false", "--out", str(out)]) == 0
    assert main(["plot", str(out)]) == 0
    fig = captured_figures[-1]
    _check_labelled(fig)
    assert any("gain switch to optimal-flight at 2 s" in t for t in fig["axes"][0]["legend"])
    assert all(ax["vlines_x"] == [2.0] for ax in fig["axes"])
