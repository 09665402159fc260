"""The rotorlab log format: one Parquet table per run, shared by the simulator (writer) and the
identification tools (reader).

- column ``t``: time in s, strictly increasing, uniform at the logging rate;
- one float column per signal;
- schema metadata ``b"units"``: JSON ``{column: unit}``;
- schema metadata ``b"rotorlab"``: JSON with run information (vehicle, scene, seed, dt, ...) and
  ``format_version``.

numpy/pyarrow only, so the simulator can import it without pulling in identification code.
"""

from __future__ import annotations

import json

__all__ = ["TIME_COLUMN", "UNITS_KEY", "META_KEY", "FORMAT_VERSION", "encode_metadata", "decode_metadata"]

TIME_COLUMN = "t"
UNITS_KEY = b"units"
META_KEY = b"rotorlab"
FORMAT_VERSION = 1


def encode_metadata(units: dict | None = None, meta: dict | None = None) -> dict[bytes, bytes]:
    """Schema metadata for a log: units and run information as JSON (``format_version`` added)."""
    units = dict(units or {})
    units.setdefault(TIME_COLUMN, "s")
    info = {"format_version": FORMAT_VERSION, **(meta or {})}
    return {UNITS_KEY: json.dumps(units).encode(), META_KEY: json.dumps(info, default=_plain).encode()}


def decode_metadata(md: dict | None, source: str = "log") -> tuple[dict, dict]:
    """``(units, meta)`` from a Parquet schema's metadata (empty dicts where a key is missing).

    Raises
    ------
    rotorlab.errors.DataError
        A key that is not a JSON object (naming ``source`` and the key).
    """
    from rotorlab.errors import DataError

    md = md or {}
    out = []
    for key in (UNITS_KEY, META_KEY):
        if key not in md:
            out.append({})
            continue
        try:
            val = json.loads(md[key])
        except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError is a ValueError
            raise DataError(f"{source}: schema metadata '{key.decode()}': expected a JSON object; "
                            f"got unreadable JSON ({exc})") from None
        if not isinstance(val, dict):
            raise DataError(f"{source}: schema metadata '{key.decode()}': expected a JSON object; "
                            f"got {type(val).__name__}")
        out.append(val)
    return out[0], out[1]


def _plain(o):
    # numpy scalars and arrays in run info (seeds, gains) become plain JSON values
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
