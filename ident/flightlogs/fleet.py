"""A fleet of flight logs: every log of a folder identified through the project's executor, one folder of model
files per log and one summary table (CSV and Markdown) for the fleet.

Each log is one task (:func:`identify_flight_log` in a worker: local processes, a local Dask cluster or a Dask
scheduler); results come back in the order of the logs, so the table does not depend on where the tasks ran.
A log that cannot be identified is a row with its error, not the end of the fleet.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

from rotorlab import atomic
from rotorlab.errors import DataError
from rotorlab.executor import Executor, map_tasks

from . import READERS

__all__ = ["FleetResult", "find_logs", "identify_fleet", "COLUMNS"]

COLUMNS = ("log", "format", "autopilot", "version", "axis", "kind", "method", "rate_hz", "vaf_holdout_pct",
           "model_file", "error")


@dataclass
class FleetResult:
    """What :func:`identify_fleet` wrote: one row per log, axis and model (``COLUMNS``; a log that failed has
    one row with its ``error``), and the summary files."""

    rows: list = field(default_factory=list)
    files: list = field(default_factory=list)

    @property
    def failed(self) -> list:
        return [r for r in self.rows if r["error"]]


def _is_csv_export(p: Path) -> bool:
    return p.is_dir() and any(p.glob("*.csv"))


def find_logs(folder) -> list[Path]:
    """The flight logs directly in ``folder``, sorted by name: files with a reader's suffix (``.ulg``, ``.bin``,
    ``.log``) and sub-folders that are ulog2csv exports (hold CSV files).

    Raises
    ------
    DataError
        ``folder`` is not a folder or holds no flight log.

    Examples
    --------
    >>> find_logs("flights/")  # doctest: +SKIP
    [PosixPath('flights/00000012.BIN'), PosixPath('flights/log002_csv'), PosixPath('flights/race.ulg')]
    """
    root = Path(folder)
    if not root.is_dir():
        raise DataError(f"{root}: a fleet is a folder of flight logs; got {'a file' if root.exists() else 'nothing'}")
    suffixes = {s for r in READERS.values() for s in r.suffixes}
    logs = sorted(p for p in root.iterdir() if (p.is_file() and p.suffix.lower() in suffixes) or _is_csv_export(p))
    if not logs:
        raise DataError(f"{root}: no flight log in the folder (expected files ending "
                        f"{', '.join(sorted(suffixes))} or ulog2csv sub-folders)")
    return logs


def _out_name(path: Path, taken: set) -> str:
    # a .ulg and a .bin of one stem, or a folder and a file, get different model folders
    name = path.name.replace(".", "_")
    while name in taken:
        name += "_"
    taken.add(name)
    return name


def _one(task) -> list[dict]:
    """Identify one log (a worker's task): its rows, or one row with the error."""
    from .run import identify_flight_log

    path, out, axes, kwargs = task
    base = {k: "" for k in COLUMNS}
    base["log"] = str(path)
    try:
        res = identify_flight_log(path, out, axes, **kwargs)
    except DataError as exc:
        return [{**base, "error": str(exc)}]
    log = res.log
    base.update(format=log.format, autopilot=log.autopilot, version=log.version)
    rows = []
    for axis, models in res.models.items():
        for kind, m in models.items():
            rows.append({**base, "axis": axis, "kind": kind, "method": m.model.method, "rate_hz": 1.0 / m.dt,
                         "vaf_holdout_pct": m.vaf_holdout, "model_file": str(Path(out) / f"{axis}-{kind}.json")})
    return rows


def _fmt(v) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def _markdown(rows) -> str:
    cols = [c for c in COLUMNS if c != "model_file"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r[c]).replace("|", "/").replace("\n", " ") for c in cols) + " |")
    return "\n".join(lines) + "\n"


def identify_fleet(folder, out_dir, axes=None, *, executor: Executor | None = None, report: bool = False,
                   **kwargs) -> FleetResult:
    """Identify every flight log of ``folder`` (:func:`find_logs`) and write the fleet summary.

    Each log's model files go to ``out_dir/<log name>/`` (as ``rotorlab ident LOG --out`` writes them, the HTML
    report only with ``report``); ``out_dir/fleet.csv`` and ``out_dir/fleet.md`` list per log, axis and model
    kind the method, the identification rate and the held-out VAF (or the log's error).

    Parameters
    ----------
    folder : str or Path
    out_dir : str or Path
    axes : sequence of str, optional
        As :func:`identify_flight_log` (``None``: every axis each log has with excitation).
    executor : rotorlab.executor.Executor, optional
        Where the logs run (``get_executor("dask://HOST:PORT")``); default: in this process.
    report : bool
        Write each log's HTML report and PNGs.
    **kwargs
        Passed to :func:`identify_flight_log` (``holdout``, ``rate_hz``, ``allow_truncated``).

    Raises
    ------
    DataError
        The folder holds no flight log.

    Examples
    --------
    >>> from rotorlab.executor import get_executor
    >>> with get_executor("dask") as ex:  # doctest: +SKIP
    ...     res = identify_fleet("flights/", "models/", executor=ex)
    >>> [r["vaf_holdout_pct"] for r in res.rows]  # doctest: +SKIP
    """
    logs = find_logs(folder)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    taken: set = set()
    tasks = [(str(p), str(out / _out_name(p, taken)), None if axes is None else list(axes),
              {**kwargs, "report": report}) for p in logs]
    res = FleetResult()
    for rows in map_tasks(_one, tasks, executor=executor, desc="fleet"):
        res.rows += rows
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in res.rows:
        w.writerow({k: _fmt(v) for k, v in r.items()})
    res.files.append(atomic.write_text(out / "fleet.csv", buf.getvalue()))
    res.files.append(atomic.write_text(out / "fleet.md", _markdown(res.rows)))
    return res
