"""The ``rotorlab`` command line.

Each sub-command lives in its own module under ``rotorlab.commands`` exposing ``add_parser(subparsers)``
and ``run(args) -> int``; modules are imported lazily so ``rotorlab ident`` never loads MuJoCo.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# command name -> module under rotorlab.commands
COMMANDS = {
    "list": "list_",
    "run": "run",
    "ident": "ident",
    "tune": "tune",
    "pipeline": "pipeline",
    "montecarlo": "montecarlo",
    "view": "view",
}


from rotorlab.errors import RotorlabError


class CLIError(RotorlabError):
    """A user-facing error raised by a command: printed without a traceback, exit status 2."""


def _available():
    for name, mod in COMMANDS.items():
        try:
            yield name, importlib.import_module(f"rotorlab.commands.{mod}")
        except ModuleNotFoundError as exc:
            if exc.name != f"rotorlab.commands.{mod}":
                raise


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rotorlab", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, mod in _available():
        p = mod.add_parser(sub)
        p.set_defaults(_module=mod)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._module.run(args) or 0)
    except RotorlabError as exc:
        # every deliberate rotorlab error (bad file, unknown name, bad data) already says what and where;
        # matching on the base class also holds when this module runs as __main__ (python -m rotorlab.cli)
        print(f"rotorlab {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
