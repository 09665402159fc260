"""Atomic file writes: write to a temporary file beside the target, fsync, then rename.

A crash or a full disk leaves either the old file or no file, never a half-written one. The temporary file is
created with mode 0666 minus the user's umask, as ``open()`` would create the target itself (``mkstemp``'s 0600
would make every log, report and gains file unreadable to the user's group).

Outputs never overwrite inputs. Each command states its outputs against its inputs before any work
(:func:`check_output`: the same path, a symlink or a hard link to an input is refused, as is an output that is
an existing folder); and, while a command runs (:func:`guarding_inputs`, entered by ``rotorlab.cli.main``),
every input file read through :func:`rotorlab.config.read_input` or named to :func:`note_input` is recorded,
and an atomic write onto any of them is refused, whatever the command.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
from pathlib import Path

import numpy as np

from rotorlab.errors import ConfigError


def _create_temp(folder: Path, name: str, suffix: str) -> Path:
    """A new empty file beside the target, created exclusively with the umask applied by the kernel."""
    while True:
        tmp = folder / f".{name}.{secrets.token_hex(4)}{suffix}.tmp"
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue


#: resolved paths of the input files read by the running command; None outside :func:`guarding_inputs`
_INPUTS: list[Path] | None = None


@contextlib.contextmanager
def guarding_inputs():
    """While active, inputs are recorded (:func:`note_input`) and no atomic write may replace one."""
    global _INPUTS
    saved, _INPUTS = _INPUTS, []
    try:
        yield
    finally:
        _INPUTS = saved


def note_input(path) -> None:
    """Record ``path`` as an input of the running command (no effect outside :func:`guarding_inputs`)."""
    if _INPUTS is not None:
        p = Path(path).resolve()
        if p not in _INPUTS:
            _INPUTS.append(p)


def _same_file(a: Path, b: Path) -> bool:
    """Whether writing ``a`` would replace ``b``: the same resolved path, or the same file by another name
    (a hard link: ``os.path.samefile``)."""
    if Path(a).resolve() == Path(b).resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist: not the same file
        return False


def _refuse_input(path: Path, inputs, flag: str | None) -> None:
    for inp in inputs:
        if _same_file(path, inp):
            raise ConfigError(f"the output is the input file {inp}: writing it would destroy the input",
                              field=flag, expected="an output path that is none of the command's input files",
                              got=str(path))


def check_output(path, inputs=(), flag: str = "--out", what: str = "file") -> Path:
    """Check an output path before any work: not an existing folder, not any of ``inputs`` (nor any input
    recorded so far), in a folder that can be written (:func:`check_writable_dir`). Records ``inputs`` as
    inputs (:func:`note_input`). ``what``: "file", or "folder" for an output folder.

    Raises
    ------
    rotorlab.errors.ConfigError
        Naming the option (``flag``), the path and the input it would overwrite.
    """
    path = Path(path)
    inputs = [Path(p) for p in inputs if p is not None]
    for inp in inputs:
        note_input(inp)
    if what == "file" and path.is_dir():
        raise ConfigError(f"{path} is an existing folder", field=flag, expected="the path of a file to write",
                          got=str(path))
    if what == "folder" and path.exists() and not path.is_dir():
        raise ConfigError(f"{path} is an existing file", field=flag, expected="a folder (new or existing)",
                          got=str(path))
    _refuse_input(path, inputs + list(_INPUTS or ()), flag)
    check_writable_dir(path if what == "folder" else (path.parent if str(path.parent) else Path(".")),
                       f"folder of {flag}" if what == "file" else flag)
    return path


@contextlib.contextmanager
def atomic_path(path, suffix: str = ""):
    """Yield a temporary path in the target's folder; on success it is renamed onto ``path``.

    Raises
    ------
    rotorlab.errors.ConfigError
        ``path`` is an existing folder, or an input of the running command (see the module docstring).
    """
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"cannot write {path}: it is an existing folder", expected="the path of a file",
                          got=str(path))
    if _INPUTS:
        _refuse_input(path, _INPUTS, None)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _create_temp(path.parent, path.name, suffix)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def check_writable_dir(path, what: str = "output folder") -> Path:
    """Create ``path`` if needed and prove a file can be created in it, before any costly work is done.

    A probe file is the only reliable test (permissions, read-only or full file systems, running as root).

    Raises
    ------
    rotorlab.errors.ConfigError
        Naming the folder and the operating system's reason.
    """
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
        os.unlink(_create_temp(p, "probe", ""))
    except OSError as exc:
        raise ConfigError(f"cannot write into the {what} ({exc.strerror or exc})", file=p,
                          expected="a writable folder") from None
    return p


def write_text(path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_bytes(path, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_json(path, obj, **kw) -> Path:
    return write_text(path, json.dumps(obj, indent=2, sort_keys=False, default=_jsonable, **kw) + "\n")


def _jsonable(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
