"""Error types with the message format every rotorlab input check uses: what, where, expected, got."""

from __future__ import annotations


class RotorlabError(Exception):
    """Base class of every error rotorlab raises on purpose."""


class ConfigError(RotorlabError, ValueError):
    """A configuration file or argument is wrong.

    The message names the file, the field, what was expected and what was found.
    """

    def __init__(self, message: str | None = None, *, file=None, field: str | None = None,
                 expected=None, got=None, hint: str | None = None):
        parts = []
        if file is not None:
            parts.append(f"{file}")
        if field is not None:
            parts.append(f"field '{field}'")
        head = ": ".join(parts)
        body = message or ""
        if expected is not None:
            body += ("; " if body else "") + f"expected {expected}"
        if got is not None:
            if type(got).__module__ == "numpy" and hasattr(got, "item"):
                got = got.item()  # a numpy scalar reads as 1.0, not np.float64(1.0)
            body += ("; " if body else "") + f"got {got!r}"
        if hint:
            body += f" ({hint})"
        super().__init__(f"{head}: {body}" if head else body)
        self.file, self.field, self.expected, self.got = file, field, expected, got


class UnknownNameError(RotorlabError, KeyError):
    """An unknown vehicle, scene, scenario, gain set or loop point; lists the valid names."""

    def __init__(self, kind: str, name: str, valid):
        valid = sorted(valid)
        super().__init__(f"unknown {kind} '{name}'; valid: {', '.join(valid) if valid else '(none)'}")
        self.kind, self.name, self.valid = kind, name, valid

    def __str__(self) -> str:  # KeyError would quote the message
        return self.args[0]


class DataError(RotorlabError, ValueError):
    """Input data (a log, a signal) cannot be used as asked: says what, where and what to do."""
