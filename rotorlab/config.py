"""Reading TOML configuration files (vehicles, gains, tuning specs): one reader, one error format.

Every TOML input goes through :func:`read_toml` (file -> dict, with readable errors for a missing, unreadable,
binary or non-UTF-8 file) and then through a :class:`Table`, the one validation layer: each typed read
(``num``, ``vec``, ``str``, ``bool``, ``table``, ...) checks type, finiteness and range and records the key as
known; :meth:`Table.check_unknown` then rejects every key that no read asked for, with a "did you mean" hint.
A new configuration key is therefore one new typed read, and a misspelt optional key can never fall back to a
default silently.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from pathlib import Path

from rotorlab.errors import ConfigError

__all__ = ["read_toml", "Table", "REQUIRED", "did_you_mean"]

REQUIRED = object()  # default of a field that must be given


def read_toml(path, kind: str) -> dict:
    """Parse the TOML file ``path``; ``kind`` ("vehicle", "gains", "spec") names it in the errors."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise ConfigError(f"{kind} file not found", file=path) from None
    except IsADirectoryError:
        raise ConfigError(f"{kind} path is a directory", file=path, expected="a TOML file") from None
    except OSError as exc:
        raise ConfigError(f"cannot read the {kind} file ({exc.strerror or exc})", file=path) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file: byte {exc.start} is not UTF-8", file=path,
                          expected="a UTF-8 TOML file", got=raw[exc.start:exc.start + 8]) from None
    if "\x00" in text:
        raise ConfigError("not a text file (NUL byte)", file=path, expected="a UTF-8 TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", file=path) from None


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
    """

    def __init__(self, src, data, prefix: str = "", *, free: bool = False):
        if not isinstance(data, dict):
            raise ConfigError(file=src, field=prefix.rstrip(".") or "(top level)", expected="a table", got=data)
        self.src, self.data, self.prefix, self.free = src, data, prefix, free
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
        t = Table(self.src, val, f"{self.field(key)}.", free=free)
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

    def vec(self, key, n=None, default=REQUIRED, *, lo=None, hi=None, lo_open=False, allow_inf=False,
            min_len: int = 1) -> tuple:
        """A list of ``n`` numbers (any length >= ``min_len`` when ``n`` is None)."""
        want = f"a list of {n} finite numbers" if n else f"a list of at least {min_len} finite numbers"
        v, given = self._get(key, default, want)
        if not given:
            return v if v is None else tuple(float(x) for x in v)
        if (not isinstance(v, list) or (n is not None and len(v) != n) or len(v) < min_len
                or not all(_is_number(x) and not math.isnan(x) and (allow_inf or math.isfinite(x)) for x in v)):
            raise self.error(key, expected=want, got=v)
        for x in v:
            if (lo is not None and (x < lo or (lo_open and x == lo))) or (hi is not None and x > hi):
                rng = " and ".join(s for s in (lo is not None and f"{'>' if lo_open else '>='} {lo}",
                                               hi is not None and f"<= {hi}") if s)
                raise self.error(key, expected=f"every value {rng}", got=v)
        return tuple(float(x) for x in v)

    def str(self, key, default=REQUIRED, choices=None) -> str:
        v, given = self._get(key, default, "a string")
        if not given:
            return v
        if not isinstance(v, str) or (choices and v not in choices):
            hint = did_you_mean(v, choices) if isinstance(v, str) and choices else None
            raise self.error(key, expected=f"one of {list(choices)}" if choices else "a string", got=v, hint=hint)
        return v

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
