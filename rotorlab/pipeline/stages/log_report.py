"""Log stage 5, report: ``OUT/report/report.md`` and ``summary.json`` (every number), the parameter file and the
calibrated vehicle TOML beside them.

The report leads with what a pilot needs before flying the new parameters: per axis the log's set against the
tuned set (rate and angle step, input-disturbance peak, margins, motor-command noise) and a plain verdict; then
the evidence (identification and its held-out fit, the calibrated twin's prediction of the held-out flight, the
calibration, the twin scenarios, notes).
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

from rotorlab import atomic, autopilots
from rotorlab.ident.flightlogs.names import AXES
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable

__all__ = ["STAGE", "verdict"]

#: a tuned value this much worse than the log's (relative) counts as worse in the verdict
WORSE = 0.05
#: the twin vouches for an axis only where it predicts the held-out flight within this many VAF points of the
#: closed-loop model fitted to the same data: a twin that explains much less of the flight is not that vehicle
FIDELITY_VAF_POINTS = 10.0


def _f(x, fmt=".3g", unit=""):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:{fmt}}{unit}"


def _ms(x):
    return _f(None if x is None else 1e3 * x, ".0f", " ms")


def _deg(x):
    return _f(None if x is None else math.degrees(x), ".3g", " deg")


def _hover_noise(val: dict, axis: str, name: str):
    """High-frequency power (above the scenario's cut) of the axis command in hover, %^2; None where not logged."""
    m = (((val.get("twin") or {}).get("hover") or {}).get(name) or {}).get("all") or {}
    return ((m.get(axis) or {}).get("control") or {}).get("hf_power")


def twin_headlines(val: dict) -> dict:
    """The twin scenarios' headline figures per set: ``{(scenario, axis, figure): {set: value}}``: a gust's peak
    attitude deviation and IAE (deg, deg s) on the axis it disturbs, hover's RMS attitude error (deg) per axis;
    smaller is better in each.

    Examples
    --------
    >>> val = {"twin": {"gust-roll": {"log": {"roll": {"disturbance": {"peak_deviation": -8.0, "iae": 6.0}}},
    ...                               "tuned": {"roll": {"disturbance": {"peak_deviation": 5.0, "iae": 4.0}}}}}}
    >>> twin_headlines(val)[("gust-roll", "roll", "peak deviation (deg)")]
    {'log': 8.0, 'tuned': 5.0}
    """
    out = {}
    for key, sets in (val.get("twin") or {}).items():
        for name, m in sets.items():
            if key == "hover":
                for axis, a in ((m.get("all") or {}).items()):
                    if isinstance(a, dict) and "rms_error_deg" in a:
                        out.setdefault((key, axis, "RMS error (deg)"), {})[name] = float(a["rms_error_deg"])
                continue
            for axis, a in m.items():
                d = a.get("disturbance") if isinstance(a, dict) else None
                if d:
                    out.setdefault((key, axis, "peak deviation (deg)"), {})[name] = abs(float(d["peak_deviation"]))
                    out.setdefault((key, axis, "IAE (deg s)"), {})[name] = float(d["iae"])
    return out


def unvouched(cal: dict, axes) -> dict:
    """Axes of ``axes`` whose calibrated twin predicts the held-out flight more than :data:`FIDELITY_VAF_POINTS`
    worse than the closed-loop fit (or was not calibrated): axis -> (twin VAF, fit VAF).

    Examples
    --------
    >>> pred = {"roll": {"twin_vaf_pct": 98.7, "closed_loop_vaf_pct": 98.8},
    ...         "pitch": {"twin_vaf_pct": 38.4, "closed_loop_vaf_pct": 56.2}}
    >>> unvouched({"prediction": pred}, ["roll", "pitch"])
    {'pitch': (38.4, 56.2)}
    """
    pred = cal.get("prediction") or {}
    out = {}
    for a in axes:
        p = pred.get(a)
        if p is None or p["twin_vaf_pct"] < p["closed_loop_vaf_pct"] - FIDELITY_VAF_POINTS:
            out[a] = (None, None) if p is None else (p["twin_vaf_pct"], p["closed_loop_vaf_pct"])
    return out


def verdict(tune: dict, val: dict, cal: dict | None = None) -> tuple[list, dict, list]:
    """Plain sentences (the first says what to fly), per axis what got worse, and the axes whose tuned gains are
    recommended.

    An axis's tuned gains are recommended when they meet the hard goals on the identified plant and, on the
    calibrated twin, are stable, keep the disk margin and reject an input disturbance at least as well as the log's
    (within :data:`WORSE`); a higher gyro-noise gain or motor-command noise is listed to weigh, not a refusal. Where
    the twin does not predict the flight (:func:`unvouched`) the first sentence says the tuned set is not validated.
    """
    lines, worse, recommended = _verdict(tune, val, cal)
    left = [a for a in AXES if a not in (tune.get("axes") or [])]
    if left and "axes" in tune:
        lines.append(f"{', '.join(left)}: not tuned (no plant model predicts the flight well enough, see the notes): "
                     "keep the log's gains there; the parameter file leaves them out.")
    return lines, worse, recommended


def recommended_file(tune: dict, recommended: list) -> str:
    """The parameter file the verdict names: the tune stage's when every tuned axis is recommended, else
    ``recommended.params`` / ``.parm`` (the report stage writes it with those axes' gains only)."""
    if recommended == list(tune["axes"]):
        return tune["params_file"]
    return "recommended" + Path(tune["params_file"]).suffix


def _axis_checks(tune: dict, val: dict, axis: str) -> tuple[list, list]:
    """(blocking, to weigh): what is worse with the tuned gains than with the log's on ``axis``."""
    an = tune["analysis"]
    lin = (val.get("linear") or {}).get(axis) or {}
    if not an["tuned"][axis]["stable"] or not all(v.get("stable", True) for v in (lin.get("tuned") or {}).values()):
        return ["unstable on the calibrated twin"], []
    block, weigh = [], []
    if an["tuned"][axis]["disk_alpha"] < an["log"][axis]["disk_alpha"] * (1 - WORSE):
        block.append(f"disk margin {an['log'][axis]['disk_alpha']:.3f} -> {an['tuned'][axis]['disk_alpha']:.3f}")
    dl, dt = (lin.get(s, {}).get("disturbance", {}).get("peak_rad") for s in ("log", "tuned"))
    if dl is not None and dt is not None and dt > dl * (1 + WORSE):
        block.append(f"disturbance peak {math.degrees(dl):.3g} -> {math.degrees(dt):.3g} deg")
    if an["tuned"][axis]["noise_gain"] > an["log"][axis]["noise_gain"] * (1 + WORSE):
        weigh.append(f"gyro-noise gain {an['log'][axis]['noise_gain']:.3g} -> {an['tuned'][axis]['noise_gain']:.3g}")
    hl, ht = _hover_noise(val, axis, "log"), _hover_noise(val, axis, "tuned")
    if hl and ht and ht > hl * (1 + WORSE):
        weigh.append(f"motor-command noise in hover {hl:.3g} -> {ht:.3g} %^2")
    for (key, ax, fig), by in twin_headlines(val).items():
        if ax == axis and {"log", "tuned"} <= set(by) and by["tuned"] > by["log"] * (1 + WORSE):
            weigh.append(f"{key} {fig} {by['log']:.3g} -> {by['tuned']:.3g}")
    return block, weigh


def _verdict(tune: dict, val: dict, cal: dict | None) -> tuple[list, dict, list]:
    if "skipped" in tune:
        return [f"Nothing was tuned: {tune['skipped']}. Keep the log's parameters."], {}, []
    if tune.get("failed"):
        return [f"Do not fly the tuned set: hard goals not met ({'; '.join(tune['failed'])}); its file "
                f"`{tune['params_file']}` is marked as failing. Keep the log's parameters."], {}, []
    if "skipped" in val:
        return [f"Not validated: {val['skipped']}. Keep the log's parameters."], {}, []
    stopped = [f"{k}: {r['tuned']['stopped']}" for k, r in (val.get("twin") or {}).items()
               if (r.get("tuned") or {}).get("stopped")]
    if stopped:
        return [f"Do not fly the tuned set: the twin did not complete {'; '.join(stopped)}."], {}, []
    checks = {a: _axis_checks(tune, val, a) for a in tune["axes"]}
    worse = {a: b + w for a, (b, w) in checks.items() if b + w}
    recommended = [a for a, (b, _) in checks.items() if not b]
    keep = [f"{a}: keep the log's gains: the tuned ones are worse on the calibrated twin ({'; '.join(b)})."
            for a, (b, _) in checks.items() if b]
    weigh = [f"{a}: to weigh, worse than the log's set on the twin: {'; '.join(w)}."
             for a, (b, w) in checks.items() if w and not b]
    if not recommended:
        return ["Keep the log's parameters: the tuned set meets its hard goals on the identified plants but is "
                "worse than the log's on the calibrated twin on every tuned axis."] + keep, worse, []
    f = recommended_file(tune, recommended)
    weak = {a: v for a, v in unvouched(cal or {}, recommended).items()}
    if weak:
        said = "; ".join(f"{a}: twin {t:.1f} % against the fit's {c:.1f} %" if t is not None else f"{a}: not calibrated"
                         for a, (t, c) in weak.items())
        first = (f"Not validated on {', '.join(weak)}: the calibrated twin predicts the held-out flight much worse than "
                 f"the closed-loop fit ({said}), so its checks do not vouch for the tuned gains there. `{f}` "
                 f"({', '.join(recommended)}) meets its hard goals on the identified plants; fly it only with care "
                 "(hover, the log's parameters at hand to switch back), or fly a log with more excitation first.")
    else:
        first = (f"Fly `{f}` ({', '.join(recommended)}): it meets its hard goals (crossover band, disk margin floor, "
                 "gyro-noise bound) on the identified plants and, on the calibrated twin, keeps the log's margins and "
                 "rejects an input disturbance at least as well.")
    return ([first] + keep + weigh
            + ["First flight: hover with a switch back to the log's parameters at hand, then small steps per axis."],
            worse, recommended)


def _pilot(ident, cal, tune, val) -> list:
    out = ["## Before you fly", ""]
    v_lines, _, recommended = verdict(tune, val, cal)
    out += [f"**Verdict.** {v_lines[0]}", ""] + [f"- {x}" for x in v_lines[1:]] + [""]
    if ident["autopilot"] != ident["log_autopilot"]:
        out += [f"The log flew {ident['log_autopilot']}; the {ident['autopilot']} structure was tuned, so the `log` set "
                f"below is {ident['autopilot']}'s defaults.", ""]
    if "skipped" in tune or "skipped" in val:
        return out
    out += ["Per axis, the log's parameters (`log`) against the tuned set (`tuned`), on the calibrated twin's "
            f"linearisation: a {math.degrees(val['rate_step_rad_s']):.0f} deg/s rate step (acro), a "
            f"{math.degrees(val['angle_step_rad']):.0f} deg angle step, the angle's peak after an input-disturbance "
            f"step of {val['dist_step']:g} (normalised torque: {100 * val['dist_step']:g} % of the full command); "
            "margins at the plant input and the gyro-noise gain on the identified plant; "
            "motor-command noise: high-frequency power of the axis command in the twin's hover in turbulence.", "",
            "| axis | set | rate rise / overshoot | angle rise / overshoot / settle | disturbance peak | "
            "disk margin (GM, PM) | noise gain | hover command HF power |",
            "|---|---|---|---|---|---|---|---|"]
    for axis in tune["axes"]:
        for name in ("log", "tuned"):
            lin = val["linear"][axis][name]
            an = tune["analysis"][name][axis]
            r, a = lin["rate"], lin["attitude"]
            rate = (f"{_ms(r['rise_time_s'])} / {_f(r['overshoot_pct'], '.1f', ' %')}" if r.get("stable")
                    else "unstable")
            ang = (f"{_ms(a['rise_time_s'])} / {_f(a['overshoot_pct'], '.1f', ' %')} / {_ms(a['settling_time_s'])}"
                   if a.get("stable") else "unstable")
            dist = _deg(lin["disturbance"].get("peak_rad"))
            marg = (f"{an['disk_alpha']:.3f} ({an['gm_db']:.1f} dB, {an['pm_deg']:.0f} deg)" if an["stable"]
                    else "unstable")
            out.append(f"| {axis} | {name} | {rate} | {ang} | {dist} | {marg} | {_f(an['noise_gain'])} | "
                       f"{_f(_hover_noise(val, axis, name))} |")
    heads = twin_headlines(val)
    if heads:
        out += ["", "In the twin itself (MuJoCo, nonlinear, the autopilot's laws flown; the same gusts and turbulence "
                "for both sets; smaller is better):", "", "| scenario | axis | figure | log | tuned |",
                "|---|---|---|---|---|"]
        out += [f"| {key} | {axis} | {fig} | {_f(by.get('log'))} | {_f(by.get('tuned'))} |"
                for (key, axis, fig), by in heads.items()]
    if recommended:
        out += ["", f"Parameter file: `{recommended_file(tune, recommended)}` (only the recommended axes' tuned gains; "
                "load it over the flown set). Every tuned gain: `" + tune["params_file"] + "`.", ""]
    return out


def _evidence(ident, cal, tune, val) -> list:
    out = ["## Evidence", "", "### The log", "",
           "The identification's own report, with the windows, spectra and every model's held-out prediction: "
           "`stages/identify/models/report.html` in the run folder.", "",
           f"`{ident['log']}`: {ident['log_autopilot']} {ident['version']} ({ident['format']}), airborne "
           f"{ident['airborne_s']:.1f} s ({ident['airborne_source']}); tuned structure: {ident['autopilot']} at "
           f"{ident['loop_hz']:g} Hz. Parameters the log lacks, taken at the autopilot's defaults: "
           f"{', '.join(ident['log_params_defaulted']) or 'none'}.", "",
           "### Identification (free-run VAF on the held-out end of the flight)", "",
           "| axis | model | method | VAF held out |", "|---|---|---|---|"]
    for axis, kinds in ident["axes"].items():
        for kind, m in kinds.items():
            if isinstance(m, dict):  # "use" names the plant the later stages took
                used = " (used)" if kinds.get("use") == kind else ""
                out.append(f"| {axis} | {kind}{used} | {m['method']} | {_f(m['vaf_holdout_pct'], '.1f', ' %')} |")
    out += ["", "### The calibrated twin predicts the held-out flight", ""]
    if "skipped" in cal:
        out += [f"Not calibrated: {cal['skipped']}.", ""]
    else:
        out += ["The calibrated twin (linearised, gimbal scene) closed with the log's own rate controller, driven by the "
                "logged rate set-point, against the closed-loop model fitted to the same data (rate set-point -> rate); "
                "where the rate set-point is the angle loop's output (an angle mode, input `att_sp`), closed with the "
                "log's angle and rate controllers and driven by the attitude set-point, against the closed-loop model "
                "from it (attitude set-point -> rate):",
                "", "| axis | input | twin VAF | closed-loop fit VAF | plant through the controller VAF |",
                "|---|---|---|---|---|"]
        for axis, p in cal["prediction"].items():
            out.append(f"| {axis} | {p.get('input', 'rate_sp')} | {_f(p['twin_vaf_pct'], '.1f', ' %')} | "
                       f"{_f(p['closed_loop_vaf_pct'], '.1f', ' %')} ({p['closed_loop_method']}) | "
                       f"{_f(p['plant_indirect_vaf_pct'], '.1f', ' %')} |")
        flight = cal.get("flight_fit")
        refined = ""
        if flight:
            before, after = flight["ident_vaf_before_pct"], flight["ident_vaf_after_pct"]
            refined = ("; then refined on the flight (the twin closed with the log's controller, free-run VAF on the "
                       "identification windows, the held-out part unused: "
                       + ", ".join(f"{x} {before[x]:.2f} -> {after[x]:.2f} %" for x in after) + ")")
        out += ["", "### Calibration", "",
                f"Started from `{cal['start_vehicle']}`, fitted to the identified plants over 1-30 rad/s{refined}. "
                f"Inertia {', '.join(f'{x:.4g}' for x in cal['inertia_kgm2'])} kg m^2, motor lag "
                f"{', '.join(sorted({f'{x * 1e3:.1f}' for x in cal['lag_s']}))} ms, delay "
                f"{', '.join(sorted({f'{x * 1e3:.0f}' for x in cal['delay_s']}))} ms. Residual twin / model over "
                "1-30 rad/s (the frequency fit's before the refinement on the flight):", "",
                "| axis | max dB | max deg | frequency fit | at the start |", "|---|---|---|---|---|"]
        fitted = ((flight or {}).get("frequency_fit") or {}).get("residual") or cal["residual"]
        for axis, r in cal["residual"].items():
            s, f = cal["residual_start"][axis], fitted[axis]
            out.append(f"| {axis} | {r['max_db']:.2f} | {r['max_deg']:.1f} | {f['max_db']:.2f} dB, {f['max_deg']:.1f} deg "
                       f"| {s['max_db']:.2f} dB, {s['max_deg']:.1f} deg |")
        notes = list(cal["at_bounds"]) + list((flight or {}).get("notes", []))
        out += [""] + [f"- {x}" for x in notes] + ([""] if notes else [])
    if "skipped" not in tune:
        out += ["### Tuning goals (value <= 1 meets a goal)", ""]
        for axis, r in tune["results"].items():
            out.append(f"- {axis}: " + "; ".join(f"{g['goal']} {g['value']:.3f} ({'hard' if g['hard'] else 'soft'})"
                                                  for g in r["goals"]))
        for a, why in (tune.get("px4_autotune_rejected") or {}).items():
            out.append(f"- PX4 autotune baseline, {a}: {why}")
        out.append("")
    if val.get("twin"):
        out += ["### The twin (MuJoCo, the autopilot's laws flown, common random numbers)", "",
                "| scenario | metric | log | tuned |", "|---|---|---|---|"]
        for key, sets in val["twin"].items():
            rows = {}
            for name, m in sets.items():
                for k, x in _flat(m):
                    rows.setdefault(k, {})[name] = x
            for k, by in rows.items():
                out.append(f"| {key} | {k} | " + " | ".join(_f(by.get(n)) if not isinstance(by.get(n), str)
                                                           else by[n] for n in ("log", "tuned")) + " |")
        out.append("")
    for k, why in (val.get("twin_skipped") or {}).items():
        out.append(f"- {k}: {why}")
    notes = ident.get("notes", []) + cal.get("notes", [])  # the identify notes name the mapped parameters
    if notes:
        out += ["", "### Notes", ""] + [f"- {n}" for n in notes]
    return out


#: the twin scenarios' figures the report shows (the rest are in summary.json)
TWIN_FIGURES = ("peak_deviation", "iae", "recovery_time_s", "rms_error_deg", "rms", "peak", "hf_power",
                "time_saturated_pct", "position_error_rms_m", "stopped")


def _flat(m, prefix=""):
    for k, x in m.items():
        if isinstance(x, dict):
            yield from _flat(x, f"{prefix}{k}.")
        elif k in TWIN_FIGURES and (x is None or isinstance(x, (int, float, str))) and not isinstance(x, bool):
            if k != "stopped" or x:
                yield f"{prefix}{k}", float(x) if isinstance(x, int) else x


def run(ctx: StageContext) -> dict:
    ident, cal = ctx.run.result("identify"), ctx.run.result("calibrate")
    tune, val = ctx.run.result("tune"), ctx.run.result("validate")
    lines, worse, recommended = verdict(tune, val, cal)
    text = ["# rotorlab pipeline --log: from a flight log to validated parameters", ""]
    text += _pilot(ident, cal, tune, val) + _evidence(ident, cal, tune, val)
    atomic.write_text(ctx.work / "report.md", "\n".join(text) + "\n")
    files = ["report.md", "summary.json"]
    if "params_file" in tune:
        shutil.copyfile(ctx.run.stage_dir("tune") / tune["params_file"], ctx.work / tune["params_file"])
        files.append(tune["params_file"])
    name = recommended_file(tune, recommended) if recommended else None
    if name is not None and name != tune["params_file"]:
        ap = autopilots.get(tune["autopilot"])
        names = {n for a in recommended for n in ap.axis_names(a).values()}
        autopilots.write_params(ap.NAME, ctx.work / name, {k: v for k, v in tune["tuned"].items() if k in names},
                                header=f"rotorlab pipeline --log: the tuned gains of {', '.join(recommended)} only, the "
                                       f"axes the calibrated twin recommends (report.md); every tuned gain: "
                                       f"{tune['params_file']}")
        files.append(name)
    if "skipped" not in cal:
        shutil.copyfile(ctx.run.stage_dir("calibrate") / cal["vehicle"], ctx.work / "vehicle.toml")
        files.append("vehicle.toml")
    summary = jsonable({"verdict": lines, "worse": worse, "recommended": recommended, "parameter_file": name,
                        "identify": ident, "calibrate": cal, "tune": tune,
                        "validate": val, "files": files})
    atomic.write_json(ctx.work / "summary.json", summary)
    return {"verdict": lines, "recommended": recommended, "parameter_file": name, "files": files}


STAGE = Stage("report", upstream=("identify", "calibrate", "tune", "validate"), settings=(), run=run)
