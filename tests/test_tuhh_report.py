"""The TUHH part of the pipeline report: summary keys of the design experiments and the claims' verdicts."""

from rotorlab.pipeline import tuhh_report
from rotorlab.pipeline.stages.report import flatten_metrics


def _entry(peak, rec, stopped=None):
    return {ax: {"disturbance": {"peak_deviation": peak, "recovery_time_s": rec}} for ax in ("roll", "pitch")} | \
        {"stopped": stopped}


def test_summary_keys_and_claims():
    rises = (("modified-pid", 0.17), ("hinf-loopshaping", 0.22), ("hinf-loopshaping-aw", 0.22))
    raw = {"design-step": {d: {ax: {"rise_time_s": r, "overshoot_pct": 3.0} for ax in ("roll", "pitch")}
                           | {"stopped": None} for d, r in rises},
           "input-disturbance": {"modified-pid": _entry(15.5, 4.7), "hinf-loopshaping": _entry(2.1, 0.2),
                                 "hinf-loopshaping-aw": _entry(2.1, 0.2)},
           "saturating-disturbance": {"modified-pid": _entry(44.0, None, "pitch-rig: rig stop"),
                                      "hinf-loopshaping": _entry(44.0, None, "pitch-rig: rig stop"),
                                      "hinf-loopshaping-aw": _entry(19.0, 4.2)}}
    v = {sc: {d: flatten_metrics(m) for d, m in per.items()} for sc, per in raw.items()}
    tuhh_report.complete_validation(v, raw)
    for sc in ("input-disturbance", "saturating-disturbance"):
        for d in ("modified-pid", "hinf-loopshaping", "hinf-loopshaping-aw"):
            assert {"pitch.disturbance.peak_deviation", "roll.disturbance.recovery_time_s", "stopped"} <= set(v[sc][d])
    assert v["saturating-disturbance"]["hinf-loopshaping"]["pitch.disturbance.recovery_time_s"] is None
    assert v["saturating-disturbance"]["hinf-loopshaping"]["stopped"] == "pitch-rig: rig stop"
    assert [c["holds"] for c in tuhh_report.design_claims(v)] == [True, True, True, True]
    # an H-inf loop that only reaches 60 % of the PID's deviation fails the "at most half" claim
    v["input-disturbance"]["hinf-loopshaping"]["pitch.disturbance.peak_deviation"] = 9.3
    assert [c["holds"] for c in tuhh_report.design_claims(v)][1] is False
