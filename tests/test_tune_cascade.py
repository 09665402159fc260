"""Attitude cascade, goals and shipped specs against the published P2-A2 and A2-MINI/B designs."""

from pathlib import Path

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab import lti
from rotorlab.errors import ConfigError
from rotorlab.gains import load_gains
from rotorlab.tune.cascade import N_CON, N_MEAS, PlantModel, cascade_plant, cascade_structure, generalised_plant
from rotorlab.tune.goals import CrossoverBand, evaluate, objective, tune_cascade
from rotorlab.tune.hinfstruct import closed_loop
from rotorlab.tune.margins import crossover_frequencies
from rotorlab.tune.spec import load_spec, parse_spec

VEH = Path(__file__).resolve().parents[1] / "vehicles"
P2_TB = PlantModel(*published_tf("anteos-p2a2", "testbed"), "test-bed")
A2_TB = PlantModel(*published_tf("anteos-a2minib", "testbed"), "test-bed")


def _by_goal(results):
    return {r.goal: r for r in results}


def test_loops_match_hand_built_transfer_functions():
    std = load_gains(VEH / "anteos-p2a2/gains/standard.toml")["pitch"]
    Gp = cascade_plant(P2_TB, 0.02)
    K = cascade_structure(0.02, std).ss()
    Ci = lti.pid_tf(std.inner.kp, std.inner.ki, std.inner.kd, std.inner.tf, 0.02)
    Co = lti.pid_tf(std.outer.kp, 0, std.outer.kd, std.outer.tf, 0.02)
    w = np.logspace(-1, 2, 40)
    # products of frequency responses (python-control's TF algebra loses accuracy on these discrete loops)
    ci, co = lti.freqresp(Ci, w)[:, 0, 0], lti.freqresp(Co, w)[:, 0, 0]
    g = lti.freqresp(Gp, w)
    gq, gt = g[:, 0, 0], g[:, 1, 0]
    Lq = CrossoverBand("q", 1, 2).loop_tf(Gp, K)            # inner loop alone (outer open)
    np.testing.assert_allclose(lti.freqresp(Lq, w)[:, 0, 0], ci * gq, rtol=1e-8)
    Lu = CrossoverBand("u", 1, 2).loop_tf(Gp, K)            # both loops at the plant input
    np.testing.assert_allclose(lti.freqresp(Lu, w)[:, 0, 0], ci * (co * gt + gq), rtol=1e-8)
    Lt = CrossoverBand("theta", 1, 2).loop_tf(Gp, K)        # outer loop, inner closed
    np.testing.assert_allclose(lti.freqresp(Lt, w)[:, 0, 0], co * ci * gt / (1 + ci * gq), rtol=1e-8)
    # theta is the ZOH-integrated rate: theta/q -> 1/s at low frequency
    ratio = lti.freqresp(Gp, [0.01])[0, 1, 0] / lti.freqresp(Gp, [0.01])[0, 0, 0]
    assert abs(ratio * 1j * 0.01 - 1) < 1e-3
    # closed loop is stable and tracks theta_ref with zero steady-state error
    T = closed_loop(generalised_plant(Gp, inputs=("theta_ref",), outputs=("theta",)), N_MEAS, N_CON, K)
    assert lti.is_stable(T) and abs(lti.freqresp(T, [1e-4])[0, 0, 0] - 1) < 1e-4


def _values(spec, gains_file, model):
    return {r.goal: r.value for r in evaluate(spec, load_gains(gains_file), [model])}


def test_p2a2_gust_reading_checked_against_the_published_numbers():
    """Ref. 000's gust goal read on the controlled variable: the published optimum sits on the bound, as the
    optimum of the problem must, and the standard gains violate it ("need improvement in gust rejection").
    Read on the command (d_u -> u), every gain set scores about 0.03: a goal that shapes nothing."""
    spec = load_spec("anteos-p2a2")
    std = _values(spec, VEH / "anteos-p2a2/gains/standard.toml", P2_TB)
    opt = _values(spec, VEH / "anteos-p2a2/gains/optimal-testbed.toml", P2_TB)
    assert abs(opt["rejection d_u->theta"] - 1.0) < 0.05
    assert std["rejection d_u->theta"] > 1.5
    gust = next(g for g in spec.goals if g.label == "rejection d_u->theta")
    on_u = parse_spec({"cascade": {"dt": 0.02, "tune": ["outer.kp"]},
                       "goal": [{"type": "rejection", "from": "d_u", "to": "u",
                                 "weight": {"kind": "highpass", "order": 1, "gain_db": 40.0, "corner_rad_s": 10.0}}]})
    for name in ("standard", "optimal-testbed", "optimal-flight"):
        assert _values(on_u, VEH / f"anteos-p2a2/gains/{name}.toml", P2_TB)["rejection d_u->u"] < 0.05
    assert not gust.hard


def test_published_optima_are_admissible_and_active_the_standard_sets_fail():
    """Every hard goal (the paper's and our additions) admits the published optimum (value <= 1, within 0.2 %
    where it is on the bound); the optimum is active on some goal; the standard gains fail what the paper says
    they fail: the P2-A2 inner crossover (1.3 rad/s) and gust rejection, the A2-MINI/B tracking, gust and
    oscillation (damping)."""
    cases = [("anteos-p2a2", P2_TB, "optimal-testbed", ["crossover q in [3.5, 14] rad/s", "rejection d_u->theta"]),
             ("anteos-a2minib", A2_TB, "optimal", ["tracking theta_ref->theta (0.3 s)", "rejection d_u->theta",
                                                   "poles"])]
    for vehicle, model, optimum, std_fails in cases:
        spec = load_spec(vehicle)
        res = evaluate(spec, load_gains(VEH / vehicle / "gains" / f"{optimum}.toml"), [model])
        assert all(r.value <= 1.002 for r in res if r.hard), (vehicle, res)
        assert max(r.value for r in res) > 0.95, vehicle
        std = _values(spec, VEH / vehicle / "gains/standard.toml", model)
        assert all(std[g] > 1.0 for g in std_fails), (vehicle, std)
    std = _by_goal(evaluate(load_spec("anteos-p2a2"), load_gains(VEH / "anteos-p2a2/gains/standard.toml"), [P2_TB]))
    assert "1.3" in std["crossover q in [3.5, 14] rad/s"].detail


def _acceptance(spec_name, model, start, published, starts=1):
    spec = load_spec(spec_name)
    res = tune_cascade(spec, [model], load_gains(start), max_iter=30 if starts == 1 else 40, starts=starts, n_jobs=2)
    pub = evaluate(spec, load_gains(published), [model])
    assert all(r.passed for r in res.report), res.report
    assert res.objective <= objective(pub) + 1e-9
    return res, pub


def test_acceptance_p2a2_testbed_from_standard_gains():
    """The issue's acceptance on the published test-bed model: both loops cross over in 3.5-14 rad/s, the gust
    and tracking goals at least as good as the published optimum's, linear-step overshoot <= 10 %."""
    res, pub = _acceptance("anteos-p2a2", P2_TB, VEH / "anteos-p2a2/gains/standard.toml",
                           VEH / "anteos-p2a2/gains/optimal-testbed.toml")
    g = res.gains["pitch"]
    assert g.outer.b == 1.0 and g.inner.c == 1.0  # 1-DoF spec leaves the set-point weights alone
    got, ref = _by_goal(res.report), _by_goal(pub)
    for goal in ("rejection d_u->theta", "tracking theta_ref->theta (0.5 s)"):
        assert got[goal].value <= ref[goal].value, goal
    Gp = cascade_plant(P2_TB, 0.02)
    K = cascade_structure(0.02, g).ss()
    for loop in ("theta", "q"):
        wc = crossover_frequencies(CrossoverBand(loop, 1, 2).loop_tf(Gp, K))
        assert len(wc) and all(3.5 <= w <= 14.0 for w in wc), (loop, wc)
    T = closed_loop(generalised_plant(Gp, inputs=("theta_ref",), outputs=("theta",)), N_MEAS, N_CON, K)
    y = np.ravel(ct.step_response(T, np.arange(0.0, 6.0, 0.02)).outputs)
    assert 100.0 * (np.max(y) - 1.0) <= 10.0


def test_acceptance_a2minib_two_dof_from_standard_gains():
    # the standard gains violate the hard goals (response time among them) and one start gets feasible: the
    # tangent program alone stalled there (0.763 with the goals violated, issue 14); its violation stops
    # shrinking and the BFGS phase on the exact penalty of the hard goals takes over
    res, pub = _acceptance("anteos-a2minib", A2_TB, VEH / "anteos-a2minib/gains/standard.toml",
                           VEH / "anteos-a2minib/gains/optimal.toml")
    g = res.gains["pitch"]
    assert g.outer.c == 0.0 and g.inner.c == 1.0  # c flags are not optimised (as published)
    assert 0.0 <= g.inner.b <= 1.0


def test_spec_errors_name_file_field_and_valid_points(tmp_path):
    good = {"cascade": {"dt": 0.02, "tune": ["outer.kp"]},
            "goal": [{"type": "crossover", "loop": "theta", "band_rad_s": [3.5, 14.0]}]}
    assert parse_spec(good).goals[0].wc_max == 14.0
    bad = {**good, "goal": [{"type": "crossover", "loop": "pitch", "band_rad_s": [3.5, 14.0]}]}
    with pytest.raises(ConfigError, match=r"my.toml.*goal\[0\].*unknown loop point .pitch.; valid: q, theta, u"):
        parse_spec(bad, src="my.toml")
    with pytest.raises(ConfigError, match=r"cascade.tune"):
        parse_spec({**good, "cascade": {"dt": 0.02, "tune": ["outer.b"]}}, src="my.toml")
    with pytest.raises(ConfigError, match=r"goal\[0\].band_rad_s"):
        parse_spec({**good, "goal": [{"type": "crossover", "loop": "q", "band_rad_s": [3.5]}]})
    with pytest.raises(ConfigError, match=r"goal\[0\].type"):
        parse_spec({**good, "goal": [{"type": "overshoot"}]})
    p = tmp_path / "s.toml"
    p.write_text("[cascade\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_spec(p)
