"""Run logs: one Parquet table per run (``t`` in s plus one column per signal, units in the schema metadata)
and a ``run.json`` beside it with the scenario, vehicle, seed, versions and metrics.

Columns are a preallocated numpy array filled a chunk of ticks at a time, so logging costs a list extend per tick.
"""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version
from operator import itemgetter
from pathlib import Path

import numpy as np
import pyarrow as pa

from rotorlab import atomic
from rotorlab.logformat import TIME_COLUMN, encode_metadata, write_parquet

#: rows a RunLog keeps as Python floats before storing them into its array in one conversion
ROW_CHUNK = 256


class RunLog:
    """Fixed-capacity column store.

    Parameters
    ----------
    columns : dict
        Column name -> unit string (``t`` is added, in s).
    capacity : int
        Maximum number of rows (ticks).
    """

    def __init__(self, columns: dict, capacity: int):
        self.units = {TIME_COLUMN: "s", **columns}
        self._names = list(self.units)
        self._value_names = self._names[1:]
        self._index = {k: i for i, k in enumerate(self._names)}
        self._nan_fill = [np.nan] * (len(self._names) - 1)
        # a row's values gathered by one C call, twice as cheap as a get per name; a tick that lacks a column
        # takes the gets with NaN for it (append). itemgetter of one name gives the value, not a tuple.
        names = self._value_names
        self._gather = itemgetter(*names) if len(names) > 1 else lambda values: tuple(values[k] for k in names)
        self._buf = np.full((capacity, len(self._names)), np.nan)
        # rows not yet in _buf, one flat list of floats row after row: a list extend per tick, the array filled
        # ROW_CHUNK rows at a time (a numpy store per tick costs several times the extend; a flat list converts
        # without numpy discovering a nested shape, and a tick allocates no row list)
        self._flat = self._buf.reshape(-1)  # a view: _buf is C-contiguous
        self._rows = []
        self._chunk_len = ROW_CHUNK * len(self._names)
        self.n = 0

    def append(self, t: float, values: dict) -> None:
        rows = self._rows
        rows.append(t)
        try:
            rows.extend(self._gather(values))
        except KeyError:  # a column this tick did not set: NaN
            rows.extend(map(values.get, self._value_names, self._nan_fill))
        self.n += 1
        if len(rows) == self._chunk_len:
            self._flush()

    def _flush(self) -> None:
        if self._rows:
            self._flat[self.n * len(self._names) - len(self._rows): self.n * len(self._names)] = self._rows
            self._rows = []

    def __getitem__(self, name: str) -> np.ndarray:
        self._flush()
        return self._buf[: self.n, self._index[name]]

    @property
    def columns(self) -> list[str]:
        return list(self.units)

    def _bare_table(self) -> pa.Table:
        self._flush()
        return pa.table({k: np.ascontiguousarray(self._buf[: self.n, i]) for i, k in enumerate(self._names)})

    def table(self, meta: dict | None = None) -> pa.Table:
        return self._bare_table().replace_schema_metadata(encode_metadata(self.units, meta))

    def write(self, path, meta: dict | None = None) -> Path:
        """Write the Parquet file atomically (:func:`rotorlab.logformat.write_parquet` sets the metadata)."""
        return write_parquet(path, self._bare_table(), self.units, meta)


def versions() -> dict:
    # package metadata, not imports: importing python-control costs seconds and a run does not need it
    out = {}
    for pkg in ("rotorlab", "mujoco", "control", "numpy", "scipy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    out["python"] = platform.python_version()
    return out


def write_run(out_dir, log: RunLog, info: dict) -> Path:
    """Write ``log.parquet`` and ``run.json`` into ``out_dir`` (both atomic); returns the folder."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    info = {**info, "versions": versions(), "rows": log.n, "columns": log.units}
    # the vehicle's absolute path stays out of the log: a seeded log is byte-identical wherever it is made
    log.write(out / "log.parquet", meta={k: v for k, v in info.items() if k not in ("metrics", "vehicle_source")})
    atomic.write_json(out / "run.json", info)
    return out
