"""Tune the attitude cascade (outer PD on the angle, inner PID on the rate) to a specification by structured
H-inf optimisation, and write the gains TOML that rotorlab run --gains reads.

Prints the tuned gains and every goal of the spec with its value (<= 1 passes), hard or soft, pass or fail.
Exit status 1 when a hard goal fails. The spec is a TOML file or a shipped name (anteos-p2a2,
anteos-a2minib); the models are JSON files from rotorlab ident, or hand-written {num, den, dt, delay_s}.
A model whose units (carried in its file) differ from the spec's (% in, deg/s out) is refused with the factors
that convert it, or converted with --convert-units; a model without units is taken as in the spec's and the
run says so (docs/units.md).
"""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, describe, positive_int, seed_int
from rotorlab.errors import RotorlabError, UnknownNameError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("tune", help="structured H-inf tuning of the attitude cascade", **describe(__doc__))
    p.add_argument("--model", required=True, action="append",
                   help="model JSON (as written by 'rotorlab ident', or {num, den, dt, delay_s}); repeat the "
                        "option to tune on several models at once")
    p.add_argument("--spec", required=True, help="spec TOML file or built-in name (anteos-p2a2, anteos-a2minib)")
    p.add_argument("--start", default="standard",
                   help="start gains: a gains TOML file or a gain-set name of the spec's vehicle")
    p.add_argument("--out", required=True, help="gains TOML to write; when a hard goal fails nothing is written "
                                                "there and the gains go to OUT.failed.toml, marked as failing")
    p.add_argument("--starts", type=positive_int, default=4,
                   help="number of starts: the start gains, then random starts; the best is kept")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the random starts")
    p.add_argument("--jobs", type=positive_int, default=2, help="processes for the starts")
    p.add_argument("--max-iter", type=positive_int, default=40, help="outer iterations per start")
    p.add_argument("--convert-units", action="store_true",
                   help="tune on a model whose input/output units differ from the spec's (e.g. rad/s and a "
                        "normalised command against deg/s and %%) after scaling it into them; without it such a "
                        "model is refused with the factors to use (docs/units.md)")
    return p


def _start_gains(start: str, spec_path):
    from rotorlab.gains import load_gains

    p = Path(start)
    if p.suffix == ".toml" or p.exists():
        return load_gains(p)

    from rotorlab.config import read_toml
    from rotorlab.vehicles import VEHICLES_DIR

    meta = read_toml(spec_path, "spec").get("meta", {})
    vehicle = meta.get("vehicle")
    if not vehicle or not isinstance(vehicle, str):
        raise CLIError(f"--start '{start}' is not a file and the spec names no [meta] vehicle to look it up in")
    gdir = VEHICLES_DIR / vehicle / "gains"
    valid = sorted(q.stem for q in gdir.glob("*.toml"))
    if start not in valid:
        raise CLIError(str(UnknownNameError(f"gain set of {vehicle}", start, valid)))
    return load_gains(gdir / f"{start}.toml")


def run(args) -> int:
    from rotorlab import atomic
    from rotorlab.gains import save_gains
    from rotorlab.ident.modelio import load_model, model_io_units
    from rotorlab.tune.cascade import PlantModel
    from rotorlab.tune.goals import format_report, tune_cascade
    from rotorlab.tune.spec import builtin_specs, load_spec, model_in_spec_units

    try:
        atomic.check_writable_dir(Path(args.out).parent, "folder of --out")  # before minutes of tuning
        spec = load_spec(args.spec)
        spec_path = builtin_specs().get(str(args.spec), args.spec)
        models = []
        for path in args.model:
            sys_, delay_s, meta = load_model(path)
            sys_, note = model_in_spec_units(sys_, model_io_units(meta, path), spec, path, args.convert_units)
            if note:
                print(f"model {path}: {note}")
            models.append(PlantModel(sys_, delay_s, name=Path(path).stem))
        start = _start_gains(args.start, spec_path)
        res = tune_cascade(spec, models, start, starts=args.starts, seed=args.seed, n_jobs=args.jobs,
                           max_iter=args.max_iter, name=Path(args.out).stem)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    failed = [r for r in res.report if r.hard and not r.passed]
    out = Path(args.out)
    if failed:
        # a gains file that misses a hard goal must never pass for a tuned one: it goes beside --out, its header
        # says which goals failed, and --out is left as it was
        out = out.with_name(out.stem + ".failed.toml")
        header = (f"# FAILED: rotorlab tune did not meet {len(failed)} hard goal(s) of spec '{spec.name}': "
                  + "; ".join(f"{r.goal} on {r.model}" for r in failed) + "\n# do not fly these gains\n")
        atomic.write_text(out, header + res.gains.to_toml())
    else:
        save_gains(res.gains, out)
    g = res.gains[spec.axis]
    print(f"spec {spec.name}: {len(models)} model(s), {len(res.history) - 1} iterations, {res.time_s:.1f} s")
    print(f"outer PD : kp={g.outer.kp:.4f} kd={g.outer.kd:.4f} tf={g.outer.tf:.4f} b={g.outer.b:.4f} c={g.outer.c:.4f}")
    print(f"inner PID: kp={g.inner.kp:.4f} ki={g.inner.ki:.4f} kd={g.inner.kd:.4f} tf={g.inner.tf:.4f} "
          f"b={g.inner.b:.4f} c={g.inner.c:.4f}")
    print(format_report(res.report))
    if failed:
        names = ", ".join(r.goal for r in failed)
        print(f"objective (max soft goal) {res.objective:.4f}; HARD GOALS NOT MET ({names}): "
              f"{args.out} not written; the gains are in {out}, marked as failing")
        return 1
    print(f"objective (max soft goal) {res.objective:.4f}; wrote {out}")
    return 0
