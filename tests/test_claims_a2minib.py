"""Ref. 000's A2-MINI/B claims on a seeded quick pipeline run: the gains tuned to the shipped spec settle
faster than the standard set with a response time no slower, drift less in a gust (as little as the published
optimum), overshoot less and recover faster after the rope release, and lower the high-frequency command and
the pitch oscillation after the in-flight switch."""

import pytest
from helpers import claim_metrics


@pytest.fixture(scope="module")
def summary(quick_summary):
    return quick_summary("anteos-a2minib")


def test_a2minib_claims_hold_on_the_twin(summary):
    v, m = summary["validation"], claim_metrics(summary)
    assert summary["tuning"]["hard_failed"] == []
    lin = "linear_step."
    assert m("setpoint", lin + "settling_time_s", "tuned") < m("setpoint", lin + "settling_time_s", "standard")
    assert m("setpoint", lin + "rise_time_s", "tuned") <= 1.1 * m("setpoint", lin + "rise_time_s", "standard")
    peak = "pitch.disturbance.peak_deviation"
    assert m("gust", peak, "tuned") < m("gust", peak, "standard")
    assert m("gust", peak, "tuned") <= 1.05 * m("gust", peak, "optimal")
    assert m("rope-pull", "release_overshoot_deg", "tuned") < m("rope-pull", "release_overshoot_deg", "standard")
    assert m("rope-pull", "release.recovery_time_s", "tuned") < m("rope-pull", "release.recovery_time_s", "standard")
    hover = v["hover"]["tuned"]
    assert hover["after_switch.pitch.control.hf_power"] < hover["before_switch.pitch.control.hf_power"]
    # the pitch oscillation that follows: the same window of the same turbulence, standard switched to itself
    rms = "after_switch.pitch.rms_error_deg"
    assert m("hover", rms, "tuned") < m("hover", rms, "standard")
    held = {c["claim"]: c["holds"] for c in summary["claims"]}
    # "non significant overshoot increment" read on the paper's own simulation: its optimum on its test-bed model
    # (18.4 % -> 32.6 %); the standard set's closed loop there is the twin's noise-free 0.3 deg step within a point
    pub = summary["step_published"]
    assert pub["standard"]["overshoot_pct"] == pytest.approx(m("setpoint", lin + "overshoot_pct", "standard"), abs=1.0)
    allowance = pub["optimal"]["overshoot_pct"] - pub["standard"]["overshoot_pct"]
    assert 10.0 < allowance < 20.0
    assert m("setpoint", lin + "overshoot_pct", "tuned") <= m("setpoint", lin + "overshoot_pct", "standard") + allowance
    assert held["response time slightly lower with no significant overshoot increase"] is True
    assert held["reduced settling time, less oscillation on the set-point"] is True
    assert held["in-flight switch: high-frequency command oscillation lowered, pitch oscillation around the "
                "set-point reduced"] is True
    assert held["rope pull: overshoot and oscillation after the release eliminated"] is True


def test_a2minib_h_lim_tells_the_gain_sets_apart(summary):
    """Issue 12 on the A2-MINI/B: h_lim differs between the gain sets (once 11.138 for every set); the worst-case
    all-pass just above it destabilises each set and random Deltas at 1.5 h_lim find unstable loops."""
    h = summary["h_lim"]
    assert set(h) == {"standard", "optimal", "tuned"}
    assert max(h.values()) >= 1.05 * min(h.values())
    for name, m in summary["montecarlo"].items():
        assert m["worst_case"]["unstable"], name
        assert m["levels"]["1"]["fraction_unstable"] == 0.0 and m["levels"]["1.5"]["fraction_unstable"] > 0.0, name
