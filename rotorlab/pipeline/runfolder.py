"""The run folder (``OUT``) and typed access to what committed stages left in it.

Layout::

    manifest.json                 format version, rotorlab version, vehicle, seed, per-stage hashes and times
    stages/<stage>/               one folder per stage, committed whole (rename) when the stage finishes
        stage.json                the stage's input hash and its result (every number it produced)
        ...                       its files: logs (Parquet), models (JSON, rotorlab.ident.modelio), gains (TOML)
    report/                       the report stage: report.md, report.html, summary.json, figures/*.png, models/, gains/

Stages and the report read upstream files only through :class:`RunFolder`, never by path arithmetic of
their own, so the layout is written down once (here).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
from tqdm import tqdm

from rotorlab.config import read_json
from rotorlab.errors import ConfigError
from rotorlab.gains import GainSet, load_gains
from rotorlab.ident.model import IdentifiedModel
from rotorlab.ident.modelio import load_model
from rotorlab.logformat import read_parquet, write_parquet
from rotorlab.pipeline.models import load_identified, load_plant
from rotorlab.pipeline.settings import PipelineError, PipelineOptions
from rotorlab.tune.cascade import PlantModel
from rotorlab.vehicles import gains_path, list_gains

__all__ = ["RunFolder", "Stage", "StageContext", "read_manifest", "stage_dir", "stage_result", "read_log",
           "write_log", "jsonable"]


def stage_dir(out, stage: str) -> Path:
    """Committed folder of a stage: ``OUT/report`` for the report, ``OUT/stages/<stage>`` otherwise."""
    return Path(out) / ("report" if stage == "report" else f"stages/{stage}")


def stage_result(out, stage: str) -> dict:
    """The result dict a committed stage stored (raises PipelineError when the stage has not run)."""
    p = stage_dir(out, stage) / "stage.json"
    if not p.exists():
        raise PipelineError(f"stage '{stage}' has not completed in {out}")
    try:
        return read_json(p, "stage record", note=False)["result"]
    except (ValueError, UnicodeDecodeError, KeyError, TypeError) as exc:  # ConfigError is a ValueError
        raise PipelineError(f"{p}: damaged stage record ({type(exc).__name__}: {exc}); run the pipeline again "
                            "into this folder to recompute the stage") from None


def read_manifest(out) -> dict | None:
    """``OUT/manifest.json`` as a dict, or None when the folder has none."""
    p = Path(out) / "manifest.json"
    if not p.exists():
        return None
    try:
        man = read_json(p, "manifest", note=False)  # the run's own file, rewritten by the run
    except ConfigError as exc:
        raise PipelineError(f"{exc}; delete the run folder or use a new --out") from None
    if not isinstance(man, dict):
        raise PipelineError(f"{p}: expected a JSON object, got {type(man).__name__}; delete the run folder or use "
                            "a new --out")
    return man


def write_log(path: Path, columns: dict, units: dict, meta: dict) -> None:
    """One run's columns as a Parquet log in the rotorlab format (:func:`rotorlab.logformat.write_parquet`)."""
    write_parquet(path, {k: np.asarray(v, float) for k, v in columns.items()}, units, meta)


def read_log(path: Path) -> dict[str, np.ndarray]:
    """Columns of a Parquet log by name (units and run information: :func:`rotorlab.logformat.read_parquet`); a
    missing or damaged file is a PipelineError naming it."""
    try:
        return read_parquet(path)[0]
    except (OSError, pa.ArrowException) as exc:  # ArrowInvalid for a truncated file
        raise PipelineError(f"{path}: not a readable Parquet log ({exc}); run the pipeline again into this folder "
                            "to recompute the stage that wrote it") from None


def jsonable(obj):
    """``obj`` with numpy values as plain JSON values (a stage's result is stored as JSON)."""
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


class RunFolder:
    """A pipeline run folder: committed stage folders, their results, logs, models and gain sets.

    Parameters
    ----------
    path : path-like
        The run folder ``OUT``.
    vehicle : str, optional
        The run's vehicle; read from ``manifest.json`` when not given.
    """

    def __init__(self, path, vehicle: str | None = None):
        self.path = Path(path)
        self._vehicle = vehicle

    @property
    def vehicle(self) -> str:
        if self._vehicle is None:
            man = read_manifest(self.path)
            if man is None:
                raise PipelineError(f"{self.path} is not a rotorlab pipeline run folder (no manifest.json)")
            self._vehicle = man["vehicle"]
        return self._vehicle

    def manifest(self) -> dict | None:
        return read_manifest(self.path)

    def stage_dir(self, stage: str) -> Path:
        return stage_dir(self.path, stage)

    def has(self, stage: str) -> bool:
        """Whether ``stage`` has been committed."""
        return (self.stage_dir(stage) / "stage.json").exists()

    def result(self, stage: str) -> dict:
        return stage_result(self.path, stage)

    # logs -------------------------------------------------------------------------------------------------
    def experiment_log_path(self, name: str) -> Path:
        """Campaign run ``name`` ('id', 'cv', 'val', 'flight') of the experiments stage."""
        return self.stage_dir("experiments") / f"{name}.parquet"

    def experiment_log(self, name: str) -> dict[str, np.ndarray]:
        return read_log(self.experiment_log_path(name))

    def validation_log_path(self, scenario: str, gains: str) -> Path:
        """Validation run of ``scenario`` with the gain set ``gains``."""
        return self.stage_dir("validate") / "logs" / f"{scenario}__{gains}.parquet"

    def validation_log(self, scenario: str, gains: str) -> dict[str, np.ndarray]:
        return read_log(self.validation_log_path(scenario, gains))

    def validation_log_paths(self) -> list[Path]:
        d = self.stage_dir("validate") / "logs"
        return sorted(d.glob("*.parquet")) if d.exists() else []

    # models -----------------------------------------------------------------------------------------------
    def models_dir(self) -> Path:
        return self.stage_dir("identify") / "models"

    def model_path(self, name: str) -> Path:
        """Model JSON ``name`` of the identify stage (a method name, 'truth' or 'pbsid-flight')."""
        return self.models_dir() / f"{name}.json"

    def identified(self, name: str) -> IdentifiedModel:
        """Identified model ``name`` at 50 Hz (:func:`rotorlab.pipeline.models.load_identified`)."""
        return load_identified(self.model_path(name))

    def plant(self, name: str, label: str | None = None) -> PlantModel:
        """Identified model ``name`` as a tuning-library plant (:func:`rotorlab.pipeline.models.load_plant`)."""
        return load_plant(self.model_path(name), label)

    def truth(self):
        """The twin's true rate model the identify stage stored (``control.StateSpace``)."""
        return load_model(self.model_path("truth"))[0]

    def w_delta_path(self, which: str = "testbed") -> Path:
        """``W_delta`` of the test-bed model (``which='testbed'``), of the in-flight model (``'flight'``) or of the
        second-order test-bed model paired with it (``'testbed-n2'``)."""
        return self.stage_dir("bootstrap") / ("w_delta.json" if which == "testbed" else f"w_delta-{which}.json")

    def w_delta(self, which: str = "testbed"):
        """The bootstrap stage's uncertainty weight ``W_delta`` (``control.StateSpace``) of the test-bed or the
        in-flight model."""
        return load_model(self.w_delta_path(which))[0]

    def replicas_path(self) -> Path:
        return self.stage_dir("bootstrap") / "replicas.npz"

    def montecarlo_path(self) -> Path:
        return self.stage_dir("tune") / "montecarlo.npz"

    # gains ------------------------------------------------------------------------------------------------
    def tuned_gains_path(self) -> Path:
        return self.stage_dir("tune") / "tuned.toml"

    def gain_sets(self, tuned: bool = True) -> dict[str, GainSet]:
        """Shipped gain sets of the vehicle (standard first, then the published ones) and, with ``tuned``
        and when the tune stage wrote it, ``tuned``."""
        sets = {name: load_gains(gains_path(self.vehicle, name)) for name in list_gains(self.vehicle)}
        ordered = {k: sets[k] for k in ["standard"] + sorted(k for k in sets if k != "standard") if k in sets}
        if tuned and self.tuned_gains_path().exists():
            ordered["tuned"] = load_gains(self.tuned_gains_path())
        return ordered


@dataclasses.dataclass
class StageContext:
    """What a stage gets: the run folder (committed upstream stages), its own work folder (renamed into
    place when it returns), the options, the effective settings and the executor."""

    run: RunFolder
    work: Path
    opts: PipelineOptions
    settings: dict
    executor: object

    @property
    def vehicle(self) -> str:
        return self.opts.vehicle

    @property
    def seed(self) -> int:
        return int(self.opts.seed)

    def progress(self, it, desc: str, total=None):
        return tqdm(it, desc=f"  {desc}", total=total, disable=not self.opts.progress, leave=False)


@dataclasses.dataclass(frozen=True)
class Stage:
    """One pipeline stage: its name, the committed stages it reads (their output hashes enter its hash),
    the keys of :func:`rotorlab.pipeline.settings.settings_for` it depends on (a change elsewhere does not
    invalidate it) and the function that fills ``ctx.work`` and returns the stage's result dict."""

    name: str
    upstream: tuple[str, ...]
    settings: tuple[str, ...]
    run: Callable[[StageContext], dict]
