"""Atomic file writes: write to a temporary file beside the target, fsync, then rename.

A crash or a full disk leaves either the old file or no file, never a half-written one. The temporary file is
created with mode 0666 minus the user's umask, as ``open()`` would create the target itself (``mkstemp``'s 0600
would make every log, report and gains file unreadable to the user's group).
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


@contextlib.contextmanager
def atomic_path(path, suffix: str = ""):
    """Yield a temporary path in the target's folder; on success it is renamed onto ``path``."""
    path = Path(path)
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
