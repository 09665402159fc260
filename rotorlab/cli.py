"""The ``rotorlab`` command line.

Each sub-command lives in its own module under ``rotorlab.commands`` exposing ``add_parser(subparsers)``
and ``run(args) -> int``; modules are imported lazily so ``rotorlab ident`` never loads MuJoCo.

Exit status: 0 done; 1 done but goals not met or the run stopped early; 2 bad input (file, field, expected,
got) or an environment that cannot do the job (unwritable folder, unreachable scheduler); 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import sys

from rotorlab.errors import RotorlabError

# command name -> module under rotorlab.commands
COMMANDS = {
    "list": "list_",
    "run": "run",
    "ident": "ident",
    "tune": "tune",
    "pipeline": "pipeline",
    "montecarlo": "montecarlo",
    "view": "view",
    "plot": "plot",
    "bode": "bode",
    "compare": "compare",
    "vehicle": "vehicle",
    "export-mjcf": "export_mjcf",
}


class CLIError(RotorlabError):
    """A user-facing error raised by a command: printed without a traceback, exit status 2."""


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1 (counts of starts, jobs, iterations, samples)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {v}")
    return v


def seed_int(text: str) -> int:
    """argparse type: a seed, a whole number in [0, 2**32) (numpy's SeedSequence refuses negative entropy)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if not 0 <= v < 2**32:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, 2**32), got {v}")
    return v


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions kept as written (paragraphs), every option's default shown unless its help already says it
    or there is none to show (None, False, an empty list)."""

    def _get_help_string(self, action):
        h = action.help or ""
        d = action.default
        if ("default" in h or d is None or d is False or d == [] or d is argparse.SUPPRESS
                or isinstance(action, argparse._HelpAction)):
            return h
        return f"{h} (default: %(default)s)"


def describe(doc: str) -> dict:
    """``description=`` and ``formatter_class=`` for a sub-command's parser from its module docstring: the whole
    text (not its first line cut mid-sentence), without reStructuredText backticks."""
    text = inspect.cleandoc(doc)
    return {"description": text.replace("``", "").strip(), "formatter_class": HelpFormatter}


def _available():
    for name, mod in COMMANDS.items():
        try:
            yield name, importlib.import_module(f"rotorlab.commands.{mod}")
        except ModuleNotFoundError as exc:
            if exc.name != f"rotorlab.commands.{mod}":
                raise


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rotorlab", formatter_class=HelpFormatter,
        description="A virtual rotorcraft lab: MuJoCo digital twins, identification and structured H-inf tuning of\n"
                    "multirotor attitude control. rotorlab COMMAND --help describes each command.")
    sub = parser.add_subparsers(dest="command", required=True)
    for _name, mod in _available():
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
    except OSError as exc:
        # the file system refused (permissions, full disk, file-size limit): the OS names the file and the reason
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"rotorlab {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nrotorlab {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
