"""Reading and writing identification logs (Parquet in the format of :mod:`rotorlab.logformat`, or CSV with
a column map), with the data checks an identification run needs and clear errors when they fail.

Never imports MuJoCo: logs come from the simulator, a flight computer or a thrust stand alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from rotorlab.errors import DataError
from rotorlab.logformat import TIME_COLUMN, decode_metadata, write_parquet

from .timebase import time_in_seconds

__all__ = ["Log", "load_log", "write_log", "check_identifiable"]

# a time step further than this fraction from the nominal one is "non-uniform"; more than 1.5 steps is a gap
UNIFORM_RTOL = 1e-3
GAP_FACTOR = 1.5


@dataclass
class Log:
    """A loaded log.

    Attributes
    ----------
    t : ndarray
        Time stamps (s), uniform.
    data : dict[str, ndarray]
        Signals by column name (``t`` excluded).
    units : dict[str, str]
    meta : dict
        Run information from the file (``b"rotorlab"`` metadata).
    source : str
        Where it came from (for error messages).
    """

    t: np.ndarray
    data: dict
    units: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    source: str = "<memory>"
    #: the unit the file's time column was in (``t`` is always in s; :func:`rotorlab.ident.timebase.time_in_seconds`)
    time_unit: str = "s"

    @property
    def dt(self) -> float:
        """Nominal sample time (s): the median step, to 12 significant digits (time stamps accumulated as
        ``t0 + k dt`` carry round-off far below the 1e-3 uniformity tolerance; 0.02 is 0.02, not 0.0199999...)."""
        return float(f"{np.median(np.diff(self.t)):.12g}") if self.t.size > 1 else float("nan")

    @property
    def columns(self) -> list[str]:
        return list(self.data)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0

    def __len__(self) -> int:
        return int(self.t.size)

    def __contains__(self, name) -> bool:
        return name == TIME_COLUMN or name in self.data

    def __getitem__(self, name: str) -> np.ndarray:
        if name == TIME_COLUMN:
            return self.t
        if name not in self.data:
            raise DataError(f"{self.source}: no column '{name}'; columns: {', '.join(self.columns)}")
        return self.data[name]

    def to_arrays(self, u_cols: Sequence[str] | str, y_cols: Sequence[str] | str) -> tuple[np.ndarray, np.ndarray]:
        """``(u (N, m), y (N, p))`` for identification; checks the columns exist, are finite and vary."""
        u_cols = [u_cols] if isinstance(u_cols, str) else list(u_cols)
        y_cols = [y_cols] if isinstance(y_cols, str) else list(y_cols)
        for c in u_cols + y_cols:
            _check_finite(self[c], c, self.t, self.source)
            if np.ptp(self[c]) == 0:
                raise DataError(f"{self.source}: column '{c}' is constant ({float(self[c][0]):.6g}); "
                                "a constant signal carries no information for identification -- "
                                "check the column name or the experiment")
        return (np.column_stack([self[c] for c in u_cols]), np.column_stack([self[c] for c in y_cols]))

    def slice(self, start: int, stop: int | None = None) -> Log:
        """Rows ``start:stop`` as a new Log."""
        return Log(self.t[start:stop], {k: v[start:stop] for k, v in self.data.items()}, dict(self.units),
                   dict(self.meta), f"{self.source}[{start}:{'' if stop is None else stop}]", self.time_unit)

    def split(self, fraction: float) -> tuple[Log, Log]:
        """First ``fraction`` of the rows and the rest (identification / cross-validation)."""
        if not 0 < fraction < 1:
            raise ValueError(f"split fraction must be in (0, 1), got {fraction}")
        k = int(round(fraction * len(self)))
        return self.slice(0, k), self.slice(k)


def _check_finite(x: np.ndarray, col: str, t: np.ndarray, source: str):
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{source}: column '{col}' has {int(bad.sum())} NaN/inf value(s), first at row {i} "
                        f"(t = {t[i]:.6g} s); drop or interpolate those rows, or load a shorter span")


def _check_time(t: np.ndarray, source: str, resample: bool) -> None:
    if t.size < 2:
        raise DataError(f"{source}: needs at least 2 rows, has {t.size}")
    _check_finite(t, TIME_COLUMN, np.arange(t.size, dtype=float), source)
    d = np.diff(t)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0]) + 1
        raise DataError(f"{source}: time column '{TIME_COLUMN}' is not strictly increasing at row {i} "
                        f"(t = {t[i - 1]:.6g} s then {t[i]:.6g} s); sort the log or remove duplicated rows")
    if resample:
        return
    dt = float(np.median(d))
    gap = np.flatnonzero(d > GAP_FACTOR * dt)
    if gap.size:
        i = int(gap[0]) + 1
        raise DataError(f"{source}: gap in the time stamps at row {i}: {d[i - 1]:.6g} s after t = {t[i - 1]:.6g} s "
                        f"where the nominal step is {dt:.6g} s ({gap.size} gap(s) in all); load the pieces "
                        "separately, or resample onto a uniform grid (rotorlab ident --resample; in Python load_log(..., resample=True))")
    off = np.flatnonzero(np.abs(d - dt) > UNIFORM_RTOL * dt)
    if off.size:
        i = int(off[0]) + 1
        raise DataError(f"{source}: non-uniform time stamps: step {d[i - 1]:.6g} s before row {i} "
                        f"(t = {t[i]:.6g} s), nominal {dt:.6g} s ({off.size} irregular step(s)); "
                        "resample onto a uniform grid (rotorlab ident --resample; in Python load_log(..., resample=True))")


def _resample(t: np.ndarray, data: dict) -> tuple[np.ndarray, dict]:
    dt = float(np.median(np.diff(t)))
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    tu = t[0] + dt * np.arange(n)
    return tu, {k: np.interp(tu, t, v) for k, v in data.items()}


def load_log(path, columns: Sequence[str] | None = None, *, column_map: Mapping[str, str] | None = None,
             units: Mapping[str, str] | None = None, resample: bool = False, time_unit: str | None = None) -> Log:
    """Load a Parquet log (rotorlab format) or a CSV file and check it.

    Parameters
    ----------
    path : str or Path
        ``.parquet`` (units and run info read from the schema metadata) or ``.csv`` (header row).
    columns : sequence of str, optional
        Signals to load (default: all). Names are after ``column_map``.
    column_map : dict, optional
        ``{our_name: name_in_file}``, e.g. ``{'t': 'time', 'u': 'u_lon'}``; ``'t'`` must map to the time
        column if the file calls it differently. Unmapped columns keep their names.
    units : dict, optional
        Units to set or override (CSV files carry none).
    resample : bool
        Interpolate onto a uniform grid at the median step instead of failing on non-uniform stamps.
    time_unit : str, optional
        Unit of the file's time column (``s``, ``ms``, ``us``, ``ns``, or ``auto`` to accept the one detected);
        default: the column's type or the file's units metadata, else seconds where the steps are plausible
        logging steps in seconds. The rule, and the refusals: :func:`rotorlab.ident.timebase.time_in_seconds`.
        The loaded ``t`` is always in s (a converted column starts at 0).

    Returns
    -------
    Log

    Raises
    ------
    DataError
        Missing file or column, non-numeric data, non-increasing / non-uniform time, gaps, NaN (naming the
        row and column).

    Examples
    --------
    A CSV file with its own column names:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from rotorlab import ident
    >>> path = Path(tempfile.mkdtemp()) / "flight.csv"
    >>> t = np.arange(500) * 0.02
    >>> np.savetxt(path, np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",", header="time,elev,gyro_y",
    ...            comments="")
    >>> log = ident.load_log(path, column_map={"t": "time", "u_lon": "elev", "q": "gyro_y"})
    >>> log.columns, log.dt, len(log["q"])
    (['u_lon', 'q'], 0.02, 500)
    """
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise DataError(f"{source}: no such log file")
    column_map = dict(column_map or {})
    rename = {v: k for k, v in column_map.items()}
    suffix = path.suffix.lower()
    if suffix in (".parquet", ".pq"):
        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow raises several types for a corrupt file
            raise DataError(f"{source}: not a readable Parquet file ({exc})") from exc
        file_units, meta = decode_metadata(table.schema.metadata, source)
    elif suffix == ".csv":
        try:
            table = pcsv.read_csv(path)
        except Exception as exc:
            raise DataError(f"{source}: not a readable CSV file ({exc})") from exc
        file_units, meta = {}, {}
    else:
        raise DataError(f"{source}: unknown log type '{suffix}'; expected .parquet or .csv")
    names = {rename.get(n, n): n for n in table.column_names}
    missing = [v for v in column_map.values() if v not in table.column_names]
    if missing:
        raise DataError(f"{source}: the column map names column(s) {missing} that the file lacks; "
                        f"file columns: {', '.join(table.column_names)}")
    if TIME_COLUMN not in names:
        raise DataError(f"{source}: no time column '{TIME_COLUMN}'; file columns: {', '.join(table.column_names)} "
                        f"(map it: rotorlab ident --column-map t=your_time_column; in Python "
                        f"load_log(..., column_map={{'t': 'your_time_column'}}))")
    wanted = list(columns) if columns is not None else [n for n in names if n != TIME_COLUMN]
    absent = [c for c in wanted if c not in names]
    if absent:
        raise DataError(f"{source}: no column(s) {absent}; columns: {', '.join(n for n in names if n != TIME_COLUMN)}")

    def numeric(name):
        col = table.column(names[name])
        try:
            return np.asarray(col.to_numpy(zero_copy_only=False), dtype=float)
        except (TypeError, ValueError) as exc:
            raise DataError(f"{source}: column '{name}' is not numeric (type {col.type})") from exc

    t_col = table.column(names[TIME_COLUMN])
    t_raw = t_col.to_numpy(zero_copy_only=False)
    if t_raw.dtype.kind not in "iufmM":
        raise DataError(f"{source}: column '{TIME_COLUMN}' is not numeric (type {t_col.type})")
    t, t_unit = time_in_seconds(t_raw, time_unit, declared=file_units.get(names[TIME_COLUMN]), source=source,
                                column=names[TIME_COLUMN])
    data = {c: numeric(c) for c in wanted if c != TIME_COLUMN}
    _check_time(t, source, resample)
    for c, v in data.items():
        _check_finite(v, c, t, source)
    if resample:
        t, data = _resample(t, data)
    u = {rename.get(k, k): v for k, v in file_units.items()}
    u.update(units or {})
    u[TIME_COLUMN] = "s"
    return Log(t, data, {k: v for k, v in u.items() if k == TIME_COLUMN or k in data}, meta, source, t_unit)


def write_log(path, table_dict: Mapping[str, Sequence[float]], units: Mapping[str, str] | None = None,
              meta: Mapping | None = None) -> Path:
    """Write a log atomically as Parquet in the rotorlab format.

    Parameters
    ----------
    path : str or Path
    table_dict : dict
        Columns; must include ``t`` (s). All of equal length.
    units : dict, optional
        ``{column: unit}``; ``t`` defaults to ``s``.
    meta : dict, optional
        JSON-serialisable run information.

    Returns
    -------
    Path
        The file written.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from rotorlab import ident
    >>> t = np.arange(500) * 0.02
    >>> path = ident.write_log(Path(tempfile.mkdtemp()) / "log.parquet",
    ...                        {"t": t, "u_lon": np.sign(np.sin(t)), "q": np.cos(t)}, units={"u_lon": "%", "q": "deg/s"})
    >>> log = ident.load_log(path)
    >>> log.columns, log.units["q"], log.dt
    (['u_lon', 'q'], 'deg/s', 0.02)
    """
    if TIME_COLUMN not in table_dict:
        raise DataError(f"write_log {path}: the table needs a time column '{TIME_COLUMN}'")
    cols = {k: np.asarray(v, dtype=float).ravel() for k, v in table_dict.items()}
    lens = {k: v.size for k, v in cols.items()}
    if len(set(lens.values())) != 1:
        raise DataError(f"write_log {path}: columns differ in length: {lens}")
    unknown = set(units or {}) - set(cols)
    if unknown:
        raise DataError(f"write_log {path}: units given for unknown column(s) {sorted(unknown)}")
    return write_parquet(path, cols, units, meta)


def check_identifiable(log: Log, u_cols, y_cols, order: int, horizon: int, future: int | None = None) -> None:
    """Raise a :class:`DataError` if ``log`` cannot support a subspace model of ``order`` with block
    horizon ``horizon`` (past) and ``future`` (default ``horizon``).

    Conditions: the signals are finite and not constant; the order is below ``future * p`` (the extended
    observability matrix must have rank ``order``); the data Hankel matrices have at least as many
    columns as rows, ``N - past - future + 1 >= (past + future) (m + p)``, so their LQ factor is
    well posed.

    Parameters
    ----------
    log : Log
        From :func:`load_log`.
    u_cols, y_cols : sequence of str
        Input and output columns.
    order : int
        Model order.
    horizon : int
        Past horizon (block rows).
    future : int, optional
        Future horizon (default ``horizon``).

    Returns
    -------
    None
        Returns when the log can support the model; raises otherwise.

    Examples
    --------
    >>> from rotorlab import ident
    >>> from rotorlab.ident.logs import Log
    >>> t = np.arange(100) * 0.02
    >>> log = Log(t, {"u": np.sign(np.sin(3 * t)), "q": np.cos(t)}, {"u": "%", "q": "deg/s"})
    >>> ident.check_identifiable(log, ["u"], ["q"], order=2, horizon=10)     # 100 samples are enough for s = 10
    >>> ident.check_identifiable(log, ["u"], ["q"], order=2, horizon=40)
    Traceback (most recent call last):
    ...
    rotorlab.errors.DataError: ...
    """
    u, y = log.to_arrays(u_cols, y_cols)
    N, m = u.shape
    p = y.shape[1]
    f = horizon if future is None else future
    if order < 1 or horizon < 1 or f < 1:
        raise DataError(f"order and horizons must be >= 1, got order={order}, horizon={horizon}, future={f}")
    if order >= f * p:
        raise DataError(f"{log.source}: order {order} needs a future horizon above {order // p} "
                        f"(order < future x outputs = {f} x {p}); raise the horizon or lower the order")
    cols = N - horizon - f + 1
    need = (horizon + f) * (m + p)
    if cols < need:
        min_n = need + horizon + f - 1
        raise DataError(f"{log.source}: {N} samples are too few for horizons {horizon}/{f} with {m} input(s) and "
                        f"{p} output(s): need at least {min_n} ({min_n * log.dt:.3g} s at dt = {log.dt:.4g} s); "
                        "record longer or shorten the horizons")
