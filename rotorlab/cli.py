"""The ``rotorlab`` command line.

Each sub-command lives in its own module under ``rotorlab.commands`` exposing ``add_parser(subparsers)``
and ``run(args) -> int``; modules are imported lazily so ``rotorlab ident`` never loads MuJoCo.

Exit status: 0 done; 1 done but goals not met or the run stopped early; 2 bad input (file, field, expected,
got) or an environment that cannot do the job (unwritable folder, unreachable scheduler); 130 interrupted
(Ctrl-C); 143 terminated (SIGTERM or SIGHUP: handled as Ctrl-C, so a run writes the log it has and a pipeline
keeps its completed stages).

Every count and size a command takes is bounded before any work starts (:func:`bounded_int`; the bounds are in
each option's help), and no command writes over one of its input files (:mod:`rotorlab.atomic`).
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import math
import os
import signal
import sys

from rotorlab import atomic
from rotorlab.errors import RotorlabError, shown

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
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {shown(text)}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {v}")
    return v


def bounded_int(hi: int, lo: int = 1, what: str = ""):
    """argparse type: a whole number in [lo, hi]. Every count that sizes work or memory (runs, samples, starts,
    iterations) has one, so a typo (``--n 1000000000000``) is refused at once instead of running for ever."""
    def parse(text: str) -> int:
        try:  # 1e6 is a whole number too
            v = float(text) if any(c in text for c in ".eE") else int(text)
        except ValueError:
            v = math.nan
        if not math.isfinite(v) or v != int(v):
            raise argparse.ArgumentTypeError(f"expected a whole number in [{lo}, {hi}]{what}, got {shown(text)}")
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number in [{lo}, {hi}]{what}, got {shown(int(v))}")
        return int(v)
    return parse


def max_processes() -> int:
    """The most worker processes a command starts: twice the CPUs this process may use (more only share them
    and multiply the memory; 300 processes on 2 cores were accepted)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return 2 * max(1, cpus)


def process_count(text: str) -> int:
    """argparse type: a number of worker processes, at most :func:`max_processes`."""
    return bounded_int(max_processes(), what=" (twice the CPUs of this machine)")(text)


def seed_int(text: str) -> int:
    """argparse type: a seed, a whole number in [0, 2**32) (numpy's SeedSequence refuses negative entropy)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {shown(text)}") from None
    if not 0 <= v < 2**32:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, 2**32), got {shown(v)}")
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


class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where Ctrl-C would be so that the same clean-up runs."""


_received: list[str] = []  # the terminating signal received while a command runs


def _terminate(signum, frame):
    _received.append(signal.Signals(signum).name)
    raise _Terminated(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handled = (signal.SIGTERM, signal.SIGHUP)
    try:
        previous = {s: signal.signal(s, _terminate) for s in handled}
    except ValueError:  # not the main thread (an embedding program): leave its signals alone
        previous = {}
    _received.clear()
    try:
        with atomic.guarding_inputs():
            rc = int(args._module.run(args) or 0)
        if _received:  # the command handled the signal as Ctrl-C (kept what it had) and returned
            print(f"rotorlab {args.command}: terminated ({_received[0]})", file=sys.stderr)
            return 143
        return rc
    except _Terminated as exc:
        print(f"\nrotorlab {args.command}: terminated ({exc})", file=sys.stderr)
        return 143
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
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def console(argv: list[str] | None = None) -> None:
    """The ``rotorlab`` command: :func:`main`, then exit with its status. After an interrupt that stopped a
    process pool's workers mid-task the process ends at once (``os._exit``, output flushed first): the
    interpreter's exit would join the pool's manager thread, which can wait for ever on half a result
    (:meth:`rotorlab.executor.LocalExecutor._terminate`). Completed stages and logs are already on disk."""
    from rotorlab import executor

    rc = main(argv)
    if executor.ABANDONED_POOLS:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)
    sys.exit(rc)


if __name__ == "__main__":
    console()
