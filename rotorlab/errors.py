"""Error types with the message format every rotorlab input check uses: what, where, expected, got.

Every error crosses process boundaries intact: a worker's error reaches the parent (a process pool pickles it)
with its class, message and fields, whatever the class's ``__init__`` signature (:meth:`RotorlabError.__reduce__`).
"""

from __future__ import annotations

#: longest text of a ``got`` value in a message: a 5000-digit integer or a 100 kB string is summarised, not printed
GOT_MAX_CHARS = 200


def _rebuild(cls, args, state):
    """Unpickle an error without calling ``cls.__init__`` (whose signature need not take ``args``)."""
    exc = cls.__new__(cls, *args)
    exc.args = args
    exc.__dict__.update(state)
    return exc


def shown(value) -> str:
    """``repr(value)`` for a message, at most :data:`GOT_MAX_CHARS` long; never fails (Python refuses ``str`` of an
    integer beyond 4300 digits)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 600:
        return f"an integer of about {int(value.bit_length() * 0.30103)} digits"
    try:
        text = repr(value)
    except (ValueError, RecursionError):
        return f"a {type(value).__name__} too large to print"
    return text if len(text) <= GOT_MAX_CHARS else text[:GOT_MAX_CHARS - 20] + f"... ({len(text)} characters)"


class RotorlabError(Exception):
    """Base class of every error rotorlab raises on purpose."""

    def __reduce__(self):
        # the default rebuilds with cls(*self.args), which fails for a class whose __init__ takes other arguments
        # (UnknownNameError(kind, name, valid)): a pool worker's error then reached the parent as a pickling crash
        return _rebuild, (type(self), self.args, dict(self.__dict__))


class ConfigError(RotorlabError, ValueError):
    """A configuration file or argument is wrong.

    The message names the file, the field, what was expected and what was found.
    """

    def __init__(self, message: str | None = None, *, file=None, field: str | None = None,
                 expected=None, got=None, hint: str | None = None):
        parts = []
        if file is not None:
            parts.append(f"{file}")
        if field is not None:  # a command-line option is named as written (--out), a file's field quoted
            parts.append(field if field.startswith("-") else f"field '{field}'")
        head = ": ".join(parts)
        body = message or ""
        if expected is not None:
            body += ("; " if body else "") + f"expected {expected}"
        if got is not None:
            if type(got).__module__ == "numpy" and hasattr(got, "item"):
                got = got.item()  # a numpy scalar reads as 1.0, not np.float64(1.0)
            body += ("; " if body else "") + f"got {shown(got)}"
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
