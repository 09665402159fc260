"""Reading input files (vehicles, gains, tuning specs, models, controllers, run records): one reader, one error
format.

Every text input goes through :func:`read_input` (only a regular file, at most :data:`MAX_INPUT_BYTES`: a FIFO,
a device such as ``/dev/zero`` or a huge file is refused before a byte is read, so nothing hangs or fills the
memory), then :func:`read_toml` or :func:`read_json` (parse errors, nesting deeper than :data:`MAX_DEPTH` and
integers too long to convert all become a :class:`~rotorlab.errors.ConfigError` naming the file). A name read
from a file that may become part of a path goes through :func:`check_name`.

Every TOML input then goes through a :class:`Table`, the one validation layer: each typed read
(``num``, ``vec``, ``str``, ``bool``, ``table``, ...) checks type, finiteness and range and records the key as
known; :meth:`Table.check_unknown` then rejects every key that no read asked for, with a "did you mean" hint.
A new configuration key is therefore one new typed read, and a misspelt optional key can never fall back to a
default silently.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import re
import stat
import sys
import tomllib
from pathlib import Path

from rotorlab import atomic
from rotorlab.errors import ConfigError

__all__ = ["read_input", "check_input_file", "read_toml", "read_json", "read_json_object", "parse_json", "check_depth", "check_name",
           "NAME_RULE", "MAX_INPUT_BYTES", "MAX_DEPTH", "Table", "REQUIRED", "did_you_mean"]

REQUIRED = object()  # default of a field that must be given

#: largest text input read (TOML, JSON): the shipped files are a few kB, a model or run record some 100 kB
MAX_INPUT_BYTES = 32 * 2**20
#: deepest nesting of lists/tables in an input: the formats need 4; Python's parsers recurse per level
MAX_DEPTH = 32
#: a name read from a file that may become part of a file name (a vehicle's name in runs/NAME-..., a spec's
#: vehicle whose gains folder is read): letters, digits, '.', '_', '+', '-', never a path
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")
NAME_RULE = ("a name of at most 64 letters, digits, '.', '_', '+' or '-', starting with a letter or digit "
             "(no '/' or '..')")


def check_input_file(path, kind: str) -> Path:
    """``path`` if it is a regular file (after following symlinks) that can be opened; else a ConfigError.

    A FIFO blocks its reader until someone writes, and a device (``/dev/zero``) never ends: both are refused
    before they are opened.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ConfigError(f"{kind} file not found", file=path) from None
    except OSError as exc:
        raise ConfigError(f"cannot read the {kind} file ({exc.strerror or exc})", file=path) from None
    if stat.S_ISDIR(st.st_mode):
        raise ConfigError(f"{kind} path is a directory", file=path, expected=f"a {kind} file") from None
    if not stat.S_ISREG(st.st_mode):
        what = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode) or
                stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise ConfigError(f"{kind} path is not a regular file", file=path, expected=f"a regular {kind} file",
                          got=what)
    return path


def read_input(path, kind: str, max_bytes: int = MAX_INPUT_BYTES, *, note: bool = True) -> bytes:
    """The bytes of the input file ``path`` (``kind`` names it in errors): a regular file of at most
    ``max_bytes``, refused otherwise before it is read (:func:`check_input_file`). With ``note``, the file is
    recorded as an input of the running command, which no atomic write may then replace
    (:func:`rotorlab.atomic.note_input`); a file the command itself maintains (a run folder's manifest) is read
    with ``note=False``."""
    path = check_input_file(path, kind)
    if note:
        atomic.note_input(path)
    try:
        # O_NONBLOCK: should the path be swapped for a FIFO after the check, open() must not wait for a writer
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ConfigError(f"cannot read the {kind} file ({exc.strerror or exc})", file=path) from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise ConfigError(f"{kind} path is not a regular file", file=path, expected=f"a regular {kind} file")
        if st.st_size > max_bytes:
            raise ConfigError(f"{kind} file too large", file=path, expected=f"at most {max_bytes} bytes",
                              got=f"{st.st_size} bytes")
        try:
            raw = fh.read(max_bytes + 1)
        except OSError as exc:
            raise ConfigError(f"cannot read the {kind} file ({exc.strerror or exc})", file=path) from None
    if len(raw) > max_bytes:  # grew while being read
        raise ConfigError(f"{kind} file too large", file=path, expected=f"at most {max_bytes} bytes")
    return raw


def _text(raw: bytes, path, kind: str, what: str) -> str:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file: byte {exc.start} is not UTF-8", file=path,
                          expected=f"a UTF-8 {what} file", got=raw[exc.start:exc.start + 8]) from None
    if "\x00" in text:
        raise ConfigError("not a text file (NUL byte)", file=path, expected=f"a UTF-8 {what} file") from None
    return text


def check_depth(doc, path, max_depth: int = MAX_DEPTH):
    """``doc`` if no list or table in it is nested deeper than ``max_depth``; else a ConfigError naming ``path``.
    Iterative, so it cannot itself run out of stack."""
    stack = [(doc, 1)]
    while stack:
        obj, depth = stack.pop()
        if isinstance(obj, dict):
            children = obj.values()
        elif isinstance(obj, list):
            children = obj
        else:
            continue
        if depth > max_depth:
            raise ConfigError("nested too deeply", file=path, expected=f"at most {max_depth} levels of lists and "
                              "tables", got=f"more than {max_depth}")
        stack.extend((c, depth + 1) for c in children if isinstance(c, (dict, list)))
    return doc


def read_toml(path, kind: str) -> dict:
    """Parse the TOML file ``path``; ``kind`` ("vehicle", "gains", "spec") names it in the errors."""
    path = Path(path)
    text = _text(read_input(path, kind), path, kind, "TOML")
    limit = sys.get_int_max_str_digits()
    try:
        # tomllib converts integers with int(), which Python refuses beyond 4300 digits; up to
        # _TOML_INT_DIGITS the integer is read (and refused by the typed read, naming its field)
        if 0 < limit < _TOML_INT_DIGITS:
            sys.set_int_max_str_digits(_TOML_INT_DIGITS)
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", file=path) from None
    except RecursionError:
        raise ConfigError("not valid TOML: nested too deeply", file=path,
                          expected=f"at most {MAX_DEPTH} levels of arrays and tables") from None
    except ValueError as exc:  # an integer beyond _TOML_INT_DIGITS digits
        raise ConfigError(f"not valid TOML: {exc}", file=path,
                          expected=f"numbers of at most {_TOML_INT_DIGITS} digits") from None
    finally:
        sys.set_int_max_str_digits(limit)
    return check_depth(doc, path)


#: longest integer read from TOML (quadratic to convert: a second beyond a few hundred thousand digits)
_TOML_INT_DIGITS = 100_000
#: integers longer than this are read as floats (inf beyond float range), never converted digit by digit
_MAX_INT_DIGITS = 18


def _json_int(text: str):
    return int(text) if len(text.lstrip("-")) <= _MAX_INT_DIGITS else float(text)


def parse_json(text: str, src, kind: str = "JSON"):
    """Parse JSON text from ``src`` (a file or a field, for errors): invalid JSON, nesting deeper than
    :data:`MAX_DEPTH` and numbers beyond float range (read as inf, refused by the typed checks) are errors,
    never tracebacks. NaN and Infinity literals parse as Python does; the typed checks refuse them."""
    try:
        doc = json.loads(text, parse_int=_json_int)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not valid {kind} (line {exc.lineno}, column {exc.colno}: {exc.msg})", file=src) from None
    except RecursionError:
        raise ConfigError(f"not valid {kind}: nested too deeply", file=src,
                          expected=f"at most {MAX_DEPTH} levels of arrays and objects") from None
    except ValueError as exc:
        raise ConfigError(f"not valid {kind}: {exc}", file=src) from None
    return check_depth(doc, src)


def read_json(path, kind: str, *, note: bool = True):
    """Parse the JSON file ``path`` through :func:`read_input`; ``kind`` ("model", "run record") names it."""
    path = Path(path)
    return parse_json(_text(read_input(path, kind, note=note), path, kind, "JSON"), path)


def read_json_object(path, kind: str, *, note: bool = True) -> dict:
    """:func:`read_json` of a file whose top level must be an object (a run record, a manifest)."""
    doc = read_json(path, kind, note=note)
    if not isinstance(doc, dict):
        raise ConfigError(f"not a {kind}", file=path, field="(top level)", expected="a JSON object",
                          got=type(doc).__name__)
    return doc


def check_name(value, file=None, field: str | None = None) -> str:
    """``value`` if it is a safe name (:data:`NAME_RULE`), else a ConfigError naming ``file`` and ``field``.

    Every name that comes from a file and may become part of a path (run folders, gain folders) passes here, so
    a name such as ``../../x`` can never place or read files outside the folders meant."""
    if not isinstance(value, str) or not _NAME_RE.fullmatch(value) or ".." in value:
        raise ConfigError(file=file, field=field, expected=NAME_RULE, got=value)
    return value


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def did_you_mean(value: str, choices) -> str | None:
    """The hint every unknown-name error gives: the closest of ``choices`` (difflib), or None."""
    close = difflib.get_close_matches(value, list(choices), n=1)
    return f"did you mean '{close[0]}'?" if close else None


class Table:
    """Strict, typed access to one TOML table; errors name the file and the dotted field.

    Parameters
    ----------
    src : path or str
        The file, for error messages.
    data : dict
        The parsed table.
    prefix : str
        Dotted path of this table in the file (``"rig.pitch."``).
    free : bool
        A free-form table (e.g. ``[sources]``): any key is accepted.
    magnitude : (float, float), optional
        Every non-zero number read through this table (and its sub-tables) must have an absolute value in this
        range: a file of physical quantities (a vehicle) states the window once, so ``1e300`` or ``1e-300`` in any
        field is refused with that field's name before it reaches MuJoCo or overflows a product.
    """

    def __init__(self, src, data, prefix: str = "", *, free: bool = False, magnitude: tuple | None = None):
        if not isinstance(data, dict):
            raise ConfigError(file=src, field=prefix.rstrip(".") or "(top level)", expected="a table", got=data)
        self.src, self.data, self.prefix, self.free = src, data, prefix, free
        self.magnitude = magnitude
        self.known: set = set()
        self._children: list = []

    def field(self, key) -> str:
        return f"{self.prefix}{key}"

    def __contains__(self, key) -> bool:
        self.known.add(key)
        return key in self.data

    def keys(self) -> list:
        return list(self.data)

    def error(self, key, message=None, **kw) -> ConfigError:
        return ConfigError(message, file=self.src, field=self.field(key), **kw)

    def _get(self, key, default, expected):
        self.known.add(key)
        if key in self.data:
            return self.data[key], True
        if default is REQUIRED:
            raise self.error(key, "missing field", expected=expected)
        return default, False

    # -- typed reads --
    def raw(self, key, default=REQUIRED):
        return self._get(key, default, "a value")[0]

    def table(self, key, required: bool = True, *, free: bool = False) -> Table | None:
        self.known.add(key)
        if key not in self.data:
            if required:
                raise self.error(key, "missing table", expected=f"a [{self.field(key)}] table")
            return None
        val = self.data[key]
        if not isinstance(val, dict):
            raise self.error(key, expected="a table", got=val)
        t = Table(self.src, val, f"{self.field(key)}.", free=free, magnitude=self.magnitude)
        self._children.append(t)
        return t

    def num(self, key, default=REQUIRED, *, lo=None, hi=None, lo_open=False, hi_open=False,
            allow_inf=False) -> float:
        v, given = self._get(key, default, "a number")
        if not given:
            return v if v is None else float(v)
        self._check_num(key, v, lo, hi, lo_open, hi_open, allow_inf)
        return float(v)

    def int(self, key, default=REQUIRED, *, lo=None, hi=None) -> int:
        v, given = self._get(key, default, "a whole number")
        if not given:
            return v
        if not (isinstance(v, int) and not isinstance(v, bool)):
            raise self.error(key, expected="a whole number", got=v)
        self._check_num(key, v, lo, hi, False, False, False)
        return int(v)

    def _check_num(self, key, v, lo, hi, lo_open, hi_open, allow_inf, what="a finite number"):
        if _is_number(v) and isinstance(v, int) and not -1e300 < v < 1e300:
            raise self.error(key, expected=what, got=v)  # float(v) would overflow or be inf
        if not _is_number(v) or math.isnan(v) or (math.isinf(v) and not allow_inf):
            raise self.error(key, expected=what, got=v)
        low = lo is not None and (v < lo or (lo_open and v == lo))
        high = hi is not None and (v > hi or (hi_open and v == hi))
        if low or high:
            if lo is not None and hi is not None:
                rng = f"in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
            elif lo is not None:
                rng = f"{'>' if lo_open else '>='} {lo}"
            else:
                rng = f"{'<' if hi_open else '<='} {hi}"
            raise self.error(key, expected=f"a value {rng}", got=v)
        self._check_magnitude(key, v)

    def _check_magnitude(self, key, v) -> None:
        if self.magnitude is not None and v != 0 and math.isfinite(v):
            lo, hi = self.magnitude
            if not lo <= abs(v) <= hi:
                want = (f"a magnitude in [{lo:g}, {hi:g}] (or 0 where the field allows it)" if lo > 0
                        else f"a magnitude of at most {hi:g}")
                raise self.error(key, "implausible value", expected=want, got=v)

    def vec(self, key, n=None, default=REQUIRED, *, lo=None, hi=None, lo_open=False, allow_inf=False,
            min_len: int = 1) -> tuple:
        """A list of ``n`` numbers (any length >= ``min_len`` when ``n`` is None)."""
        want = f"a list of {n} finite numbers" if n else f"a list of at least {min_len} finite numbers"
        v, given = self._get(key, default, want)
        if not given:
            return v if v is None else tuple(float(x) for x in v)
        if (not isinstance(v, list) or (n is not None and len(v) != n) or len(v) < min_len
                or not all(_is_number(x) and (not isinstance(x, int) or -1e300 < x < 1e300) and not math.isnan(x)
                           and (allow_inf or math.isfinite(x)) for x in v)):
            raise self.error(key, expected=want, got=v)
        for x in v:
            if (lo is not None and (x < lo or (lo_open and x == lo))) or (hi is not None and x > hi):
                rng = " and ".join(s for s in (lo is not None and f"{'>' if lo_open else '>='} {lo}",
                                               hi is not None and f"<= {hi}") if s)
                raise self.error(key, expected=f"every value {rng}", got=v)
        for x in v:
            self._check_magnitude(key, x)
        return tuple(float(x) for x in v)

    def str(self, key, default=REQUIRED, choices=None) -> str:
        v, given = self._get(key, default, "a string")
        if not given:
            return v
        if not isinstance(v, str) or (choices and v not in choices):
            hint = did_you_mean(v, choices) if isinstance(v, str) and choices else None
            raise self.error(key, expected=f"one of {list(choices)}" if choices else "a string", got=v, hint=hint)
        return v

    def name(self, key, default=REQUIRED) -> str:
        """A name that may become part of a path (:func:`check_name`)."""
        v, given = self._get(key, default, NAME_RULE)
        return check_name(v, self.src, self.field(key)) if given else v

    def bool(self, key, default=REQUIRED) -> bool:
        v, given = self._get(key, default, "true or false")
        if given and not isinstance(v, bool):
            raise self.error(key, expected="true or false (TOML booleans, unquoted)", got=v)
        return v

    def strlist(self, key, default=REQUIRED, choices=None) -> list:
        v, given = self._get(key, default, "a list of strings")
        if given and (not isinstance(v, list) or not all(isinstance(x, str) for x in v)):
            raise self.error(key, expected="a list of strings", got=v)
        for x in (v if given and choices else ()):
            if x not in choices:
                raise self.error(key, expected=f"names among {list(choices)}", got=x, hint=did_you_mean(x, choices))
        return list(v) if v is not None else v

    # -- strictness --
    def check_unknown(self) -> None:
        """Raise for the first key of this table (or of a sub-table read through it) that no read asked for."""
        if not self.free:
            unknown = [k for k in self.data if k not in self.known]
            if unknown:
                k = unknown[0]
                raise self.error(k, "unknown key", expected=f"one of {sorted(self.known)}", got=k,
                                 hint=did_you_mean(k, sorted(self.known)))
        for child in self._children:
            child.check_unknown()
