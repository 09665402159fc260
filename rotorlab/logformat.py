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


def decode_metadata(md: dict | None) -> tuple[dict, dict]:
    """``(units, meta)`` from a Parquet schema's metadata (empty dicts where a key is missing)."""
    md = md or {}
    units = json.loads(md[UNITS_KEY]) if UNITS_KEY in md else {}
    meta = json.loads(md[META_KEY]) if META_KEY in md else {}
    return units, meta


def _plain(o):
    # numpy scalars and arrays in run info (seeds, gains) become plain JSON values
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
