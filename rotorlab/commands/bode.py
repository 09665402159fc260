"""Bode diagram of one or more models to a PNG (no display needed), and each model's poles, zeros, DC gain
and delay printed in rad/s.

The models are JSON files as rotorlab ident writes them, or hand-written {num, den, dt, delay_s} (a published
transfer function). Magnitude in dB of the gain in output units per input unit, phase in deg with the input
delay included (--no-delay leaves it out), frequency in rad/s up to the Nyquist frequency of discrete models.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rotorlab.cli import CLIError, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("bode", help="Bode diagram of model JSON files (PNG) and their poles/zeros", **describe(__doc__))
    p.add_argument("models", nargs="+", metavar="MODEL", help="model JSON file(s)")
    p.add_argument("--out", default="bode.png", help="PNG to write")
    p.add_argument("--w-min", type=float, default=0.1, help="lowest frequency, rad/s")
    p.add_argument("--w-max", type=float, default=None,
                   help="highest frequency, rad/s (default: the Nyquist frequency, or 1000 for continuous models)")
    p.add_argument("--no-delay", action="store_true", help="leave the input delay out of the phase")
    return p


def run(args) -> int:
    from rotorlab.atomic import check_output
    from rotorlab.ident.modelio import describe_model, load_model
    from rotorlab.lti import is_discrete
    from rotorlab.plotting import plot_bode

    models = []
    try:
        check_output(args.out, args.models)
        for path in args.models:
            sys, delay_s, meta = load_model(path)
            if sys.ninputs != 1 or sys.noutputs != 1:
                raise CLIError(f"{path}: a {sys.noutputs}x{sys.ninputs} model; bode draws single-input single-output "
                               "models")
            units = meta.get("units") or {}
            ins, outs = meta.get("input") or ["u"], meta.get("output") or ["y"]
            print(f"{path}:")
            print("\n".join("  " + ln for ln in describe_model(sys, delay_s, units, ins, outs)))
            models.append((Path(path).stem, sys, 0.0 if args.no_delay else delay_s,
                           (units.get(ins[0], ""), units.get(outs[0], ""))))
        nyq = min((np.pi / float(s.dt) for _, s, _, _ in models if is_discrete(s)), default=None)
        w_max = args.w_max or (0.999 * nyq if nyq else 1000.0)
        if not 0 < args.w_min < w_max:
            raise CLIError(f"--w-min must be > 0 and below the highest frequency {w_max:g} rad/s, got {args.w_min:g}")
        path = plot_bode(models, args.out, np.logspace(np.log10(args.w_min), np.log10(w_max), 400))
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None
    print(f"wrote {path}")
    return 0
