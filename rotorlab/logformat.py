"""The rotorlab log format: every Parquet file rotorlab writes (simulator runs, identification logs, the
pipeline's campaign and validation logs, Monte Carlo tables) goes through :func:`write_parquet`.

- column ``t``: time in s, strictly increasing, uniform at the logging rate (time logs; a table of Monte
  Carlo samples has no time column);
- one column per signal (float for time logs);
- schema metadata ``b"units"``: JSON ``{column: unit}``;
- schema metadata ``b"rotorlab"``: JSON with run information (vehicle, scene, seed, dt, ...) and
  ``format_version``.

numpy/pyarrow only, so the simulator can import it without pulling in identification code.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from rotorlab.atomic import atomic_path
from rotorlab.errors import DataError

__all__ = ["TIME_COLUMN", "UNITS_KEY", "META_KEY", "FORMAT_VERSION", "encode_metadata", "decode_metadata",
           "write_parquet", "read_parquet"]

TIME_COLUMN = "t"
UNITS_KEY = b"units"
META_KEY = b"rotorlab"
FORMAT_VERSION = 1


def encode_metadata(units: dict | None = None, meta: dict | None = None, *, time_column: bool = True
                    ) -> dict[bytes, bytes]:
    """Schema metadata for a log: units and run information as JSON (``format_version`` added; the time
    column's unit ``s`` added when the table has one)."""
    units = dict(units or {})
    if time_column:
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
    md = md or {}
    out = []
    for key in (UNITS_KEY, META_KEY):
        if key not in md:
            out.append({})
            continue
        try:
            val = json.loads(md[key])
        except (ValueError, UnicodeDecodeError, RecursionError) as exc:  # JSONDecodeError is a ValueError
            raise DataError(f"{source}: schema metadata '{key.decode()}': expected a JSON object; "
                            f"got unreadable JSON ({exc})") from None
        if not isinstance(val, dict):
            raise DataError(f"{source}: schema metadata '{key.decode()}': expected a JSON object; "
                            f"got {type(val).__name__}")
        out.append(val)
    return out[0], out[1]


def write_parquet(path, columns: pa.Table | Mapping, units: Mapping[str, str] | None = None,
                  meta: Mapping | None = None) -> Path:
    """Write a table (a ``pyarrow.Table`` or ``{column: values}``) atomically as Parquet with its units and
    run information in the schema metadata.

    Raises
    ------
    ValueError
        ``units`` names a column the table lacks.
    """
    table = columns if isinstance(columns, pa.Table) else pa.table(dict(columns))
    unknown = set(units or {}) - set(table.column_names)
    if unknown:
        raise ValueError(f"{path}: units given for unknown column(s) {sorted(unknown)}")
    md = encode_metadata(dict(units or {}), dict(meta or {}), time_column=TIME_COLUMN in table.column_names)
    with atomic_path(path, suffix=".parquet") as tmp:
        pq.write_table(table.replace_schema_metadata(md), tmp)
    return Path(path)


def read_parquet(path) -> tuple[dict[str, np.ndarray], dict, dict]:
    """``(columns, units, meta)`` of a Parquet file written by :func:`write_parquet` (no data checks: an
    identification run reads through :func:`rotorlab.ident.logs.load_log`, which checks)."""
    table = pq.read_table(path)
    units, meta = decode_metadata(table.schema.metadata)
    return {k: table.column(k).to_numpy(zero_copy_only=False) for k in table.column_names}, units, meta


def _plain(o):
    # numpy scalars and arrays in run info (seeds, gains) become plain JSON values
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
