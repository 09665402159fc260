"""``rotorlab tune --autopilot px4|ardupilot``: the three-axis tuning of an autopilot's own loops
(:mod:`rotorlab.tune.autopilot`) against the generic multirotor spec derived from the models
(:mod:`rotorlab.tune.autopilot_spec`), written in the autopilot's parameter format."""

from __future__ import annotations

import math
from pathlib import Path

from rotorlab.cli import CLIError
from rotorlab.errors import ConfigError, RotorlabError

AXES = ("roll", "pitch", "yaw")
# model units -> factor to the autopilot's (normalised torque in, rad/s out); rotorlab's identified models are
# command % -> deg/s
_IN = {"%": 100.0, "pct": 100.0, "norm": 1.0, "1": 1.0}
_OUT = {"deg/s": math.pi / 180.0, "dps": math.pi / 180.0, "rad/s": 1.0}


def _models(args):
    from rotorlab.ident.flightlogs.plant_structures import file_plant
    from rotorlab.ident.modelio import load_model

    axes_default = [a.strip() for a in args.axes.split(",") if a.strip()]
    for a in axes_default:
        if a not in AXES:
            raise CLIError(f"--axes: unknown axis {a!r}; expected some of {', '.join(AXES)}")
    out = {}
    for item in args.model:
        axis, sep, path = item.partition("=")
        if not sep:
            axis, path = None, item
        elif axis not in AXES:
            raise CLIError(f"--model {item}: unknown axis {axis!r}; expected AXIS=FILE with AXIS in {', '.join(AXES)}")
        # a plant through the controller (rotorlab ident's plant-indirect files) as its structure's continuous plant
        G, delay_s, meta = load_model(path, whole_samples=False)
        G, delay_s = file_plant(G, delay_s, meta)
        if G.ninputs != 1 or G.noutputs != 1:
            raise ConfigError("the model must be SISO (torque command -> rate)", file=path, field="A/B/C/D",
                              got=f"{G.noutputs} outputs x {G.ninputs} inputs")
        units = meta.get("units") or {}
        names_in, names_out = meta.get("input") or [], meta.get("output") or []
        uin = units.get(names_in[0], "%") if names_in else "%"
        uout = units.get(names_out[0], "deg/s") if names_out else "deg/s"
        if uin not in _IN or uout not in _OUT:
            raise ConfigError("unknown model units", file=path, field="units",
                              expected=f"input in {sorted(_IN)}, output in {sorted(_OUT)}", got=f"{uin} -> {uout}")
        G = G * (_IN[uin] * _OUT[uout])
        for a in ([axis] if axis else axes_default):
            out[a] = (G, float(delay_s), Path(path).name)
    return out


def _filter_key(ap, params) -> tuple:
    return tuple(float(params[n]) for group in ap.FILTER_GROUPS for n in group)


def run_autopilot(args) -> int:
    from rotorlab import atomic, autopilots
    from rotorlab.tune import autopilot as T
    from rotorlab.tune.autopilot_spec import ALL_BASELINES, generic_spec
    from rotorlab.tune.goals import format_report
    from rotorlab.tune.spec import AutopilotSpec, load_spec, parse_spec

    ap = autopilots.get(args.autopilot)
    out = Path(args.out)
    want = ".params" if ap.FILE_FORMAT == "qgc" else ".parm"
    try:
        if out.suffix.lower() not in ((".params",) if want == ".params" else (".parm", ".param")):
            raise ConfigError("wrong parameter file type for the autopilot", file=out, field="--out",
                              expected=f"a {want} file for {ap.NAME}", got=out.suffix or "(no suffix)")
        # neither output may replace an input (the current parameters, a spec, a model: --model [AXIS=]FILE)
        inputs = [args.params, args.spec, *(m.split("=", 1)[-1] for m in args.model)]
        atomic.check_output(out, inputs)
        if args.spec_out:
            atomic.check_output(args.spec_out, inputs, flag="--spec-out")
        raw = autopilots.read_params(args.params) if args.params else {}
        current = ap.TABLE.complete(raw, fill_defaults=True, source=args.params) if args.params else ap.TABLE.defaults()
        loop_hz = float(args.loop_hz) if args.loop_hz else ap.loop_hz(current)
        if not (loop_hz > 0 and math.isfinite(loop_hz)):
            raise ConfigError("loop rate must be a positive number of Hz", field="--loop-hz", got=args.loop_hz)
        dt = 1.0 / loop_hz
        models = _models(args)
        plants = {a: T.axis_plant(G, d, dt) for a, (G, d, _) in models.items()}
        baselines, rejected = T.baseline_sets(ap, plants, current, "file" if args.params else None,
                                              T.px4_autotune_settings(raw, args.params))
        if args.match and args.match not in baselines and args.match != ALL_BASELINES:
            raise ConfigError("no such baseline", field="--match", expected=" or ".join([*baselines, ALL_BASELINES]),
                              got=args.match)
        if args.spec:
            spec = load_spec(args.spec)
            if not isinstance(spec, AutopilotSpec) or spec.autopilot != ap.NAME:
                raise ConfigError("not an autopilot spec for this autopilot", file=args.spec, field="autopilot.name",
                                  expected=ap.NAME, got=getattr(spec, "autopilot", "a [cascade] spec"))
            if abs(spec.dt - dt) > 1e-9:
                raise ConfigError("the spec's loop period differs from the loop rate", file=args.spec,
                                  field="autopilot.dt", expected=dt, got=spec.dt)
        model_names = ", ".join(sorted({m[2] for m in models.values()}))
        spec_texts = {}

        def make_spec(p):
            # the generated spec depends on the filters of p (the band counts their lag); a given spec does not
            if args.spec:
                out_spec = spec
            else:
                import tomllib

                text = generic_spec(ap, {a: (plants[a], models[a][0], models[a][1]) for a in plants}, dt, p,
                                    baselines, model=model_names, match=args.match)
                spec_texts[_filter_key(ap, p)] = text
                out_spec = parse_spec(tomllib.loads(text), name="generic", src="<generated spec>")
            out_spec.axes = [a for a in out_spec.axes if a in plants]
            if not out_spec.axes:
                raise ConfigError("no model for any axis the spec tunes", field="--model", expected=", ".join(AXES))
            return out_spec

        tune_kw = dict(starts=args.starts or 1, seed=args.seed, max_iter=args.max_iter or 30, n_jobs=args.jobs)
        filters = {}
        if args.filters == "search":
            found = T.tune_filters(make_spec, plants, current, T.filter_candidates(ap, current, dt), **tune_kw)
            res, filters = found.results, found.filters
        else:
            res = T.tune_autopilot(make_spec(current), plants, current, **tune_kw)
        spec_text = spec_texts.get(_filter_key(ap, {**current, **filters}))
        if args.spec_out and spec_text is not None:
            atomic.write_text(args.spec_out, spec_text)
    except (RotorlabError, ValueError) as exc:
        raise CLIError(str(exc)) from None
    tuned = T.tuned_parameters(ap, {a: r.gains for a, r in res.items()}, filters)
    failed = [(a, x) for a, r in res.items() for x in r.report if x.hard and not x.passed]
    lines = [f"rotorlab tune --autopilot {ap.NAME}: {', '.join(res)} at {loop_hz:g} Hz on "
             + ", ".join(f"{a}={models[a][2]} (delay {models[a][1]:.4g} s)" for a in res),
             f"spec: {'generic multirotor spec (rotorlab.tune.autopilot_spec)' if spec_text else args.spec}; "
             f"baselines: {', '.join(baselines)}"
             + (f"; filters searched ({len(found.table)} settings), chosen: "
                + ", ".join(f"{k}={v:g}" for k, v in filters.items()) if filters else ""),
             "goals per axis: crossover band, disk margin floor, gyro-noise bound (hard, <= 1 met); input-disturbance "
             "peak and low-frequency rejection (soft, minimised; 1 = the best baseline's)"]
    for a, r in res.items():
        lines.append(f"{a}: " + "; ".join(
            f"{x.goal} {x.value:.3f}" + (" (hard)" + ("" if x.passed else " FAIL") if x.hard else " (soft)")
            for x in r.report))
    refusal = "; ".join(dict.fromkeys(rejected.values()))
    if refusal:
        lines.append(f"px4-autotune baseline: {refusal}")
    header = T.parameter_file_header(lines, [f"{a} {x.goal}" for a, x in failed])
    if failed:
        out = out.with_name(out.stem + ".failed" + out.suffix)
    try:
        autopilots.write_params(ap.NAME, out, tuned, header=header)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    for a, r in res.items():
        print(f"{a}: " + ", ".join(f"{k}={v:.5g}" for k, v in r.gains.items()) + f"  ({r.time_s:.2f} s)")
        print(format_report(r.report))
        for name, p in [("tuned", {**current, **tuned})] + list(baselines.items()):
            x = T.analyse_axis(ap, p, a, plants[a])
            print(f"  {name:13s} disturbance peak {x.dist_peak_rad:.4g} rad, IAE {x.dist_iae_rad_s:.4g} rad s "
                  f"(unit torque step), disk margin {x.disk_alpha:.3f}, gyro noise {x.noise_gain:.4g}")
    if refusal:
        print(f"px4-autotune baseline: {refusal}")
    if failed:
        print(f"HARD GOALS NOT MET: {args.out} not written; the parameters are in {out}, marked as failing")
        return 1
    print(f"wrote {out}")
    return 0
