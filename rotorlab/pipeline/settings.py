"""What a pipeline run was asked (:class:`PipelineOptions`) and the sizes and grids it implies
(:func:`settings_for`, part of every stage hash)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from rotorlab.errors import RotorlabError
from rotorlab.tune.cascade import DT_S

__all__ = ["FORMAT_VERSION", "DT_S", "LEVELS", "PipelineError", "PipelineOptions", "LogPipelineOptions", "LOG_LEVELS",
           "settings_for", "log_settings_for"]

# run-folder format: a folder written by another format is refused, never mixed (2: logs in rotorlab.logformat)
FORMAT_VERSION = 2

# DT_S (imported): the published flight-software and identification sample time, 0.02 s. greybox_periods: PRBS
# periods of ref. 002's three-axis campaign (the first settles, the rest are averaged: ten in the paper)

_LEVELS = {
    # campaign lengths (s): identification PRBS (three concatenated segments), cross-validation,
    # closed-loop validation, in-flight PRBS
    "full": dict(id_s=120.0, cv_s=40.0, val_s=30.0, flight_s=90.0, moesp_orders=[2, 3, 4, 5, 6],
                 moesp_horizons=[20, 30, 40], pbsid_orders=[2, 3, 4, 5, 6], pbsid_horizons=[[11, 7], [15, 10],
                 [20, 10]], lms_orders=[2, 3, 4, 5], lms_taps=60, n_boot=1000, n_mc=1000, tune_starts=8,
                 validation_s={}, record_runs=None, hinf_restarts=3, oe_restarts=2, greybox_periods=11,
                 greybox_restarts=1),
    # quick: half the campaign, the published best settings plus one alternative per grid, 50 bootstrap
    # replications, 100 Monte Carlo samples, shorter hover. Eight tuning starts (full too): the P2-A2 spec's optimum is a
    # flat valley (starts end 0.2 % apart in the objective with 5-6.5 % linear-step overshoot) and a last-bit
    # difference (another CPU's BLAS kernels) moves some starts' end points, so four starts let the best one
    # change with the CPU (overshoot 5.6 % or 4.7 % on seed 3); with six to twelve the same start wins on
    # AVX-512, with numpy's AVX-512 loops off, and with OpenBLAS's Haswell kernels (docs/reproducibility.md)
    "quick": dict(id_s=60.0, cv_s=20.0, val_s=20.0, flight_s=60.0, moesp_orders=[2, 4], moesp_horizons=[40],
                  pbsid_orders=[2, 5], pbsid_horizons=[[11, 7], [20, 10]], lms_orders=[2, 4], lms_taps=50, n_boot=50,
                  n_mc=100, tune_starts=8, validation_s={"hover": 24.0}, record_runs=4, hinf_restarts=1,
                  oe_restarts=0, greybox_periods=11, greybox_restarts=0),
    "tiny": dict(id_s=24.0, cv_s=10.0, val_s=8.0, flight_s=20.0, moesp_orders=[2, 4], moesp_horizons=[20],
                 pbsid_orders=[2], pbsid_horizons=[[11, 7]], lms_orders=[2], lms_taps=40, n_boot=8, n_mc=20,
                 tune_starts=1, validation_s={"setpoint": 7.0, "gust": 5.0, "rope-pull": 6.0, "hover": 8.0},
                 record_runs=1, hinf_restarts=0, oe_restarts=0, greybox_periods=3, greybox_restarts=0),
}
LEVELS = tuple(_LEVELS)

# The log pipeline (rotorlab pipeline --log): the identification's held-out fraction, tuning starts and
# iterations, and the twin scenarios' lengths (s; the gust starts at 2 s and lasts 1 s)
_LOG_LEVELS = {
    "full": dict(holdout=0.4, tune_starts=4, tune_max_iter=30, validation_s={"gust": 8.0, "hover": 30.0}),
    "quick": dict(holdout=0.4, tune_starts=2, tune_max_iter=30, validation_s={"gust": 6.0, "hover": 12.0}),
    "tiny": dict(holdout=0.4, tune_starts=1, tune_max_iter=8, validation_s={"gust": 3.5, "hover": 5.0}),
}
LOG_LEVELS = tuple(_LOG_LEVELS)


class PipelineError(RotorlabError):
    """The pipeline cannot run as asked (incompatible run folder, bad option)."""


@dataclasses.dataclass
class PipelineOptions:
    """What ``rotorlab pipeline`` was asked. ``level``: 'full', 'quick' or 'tiny' (tests)."""

    vehicle: str = "anteos-p2a2"
    out: Path = Path("pipeline-run")
    level: str = "full"
    seed: int = 0
    executor: str = "local"
    workers: int | None = None
    progress: bool = True
    n_boot: int | None = None
    n_mc: int | None = None
    #: an autopilot's laws to fly in the validation scenarios beside the gain sets (``px4:PARAMS``,
    #: ``ardupilot:PARAMS``, ``PARAMS`` a parameter file or ``defaults``; ``--controller``)
    controller: str | None = None


@dataclasses.dataclass
class LogPipelineOptions(PipelineOptions):
    """What ``rotorlab pipeline --log`` was asked: the flight log, the vehicle TOML to start the twin from (None:
    the shipped x500 twin, PX4's reference vehicle), the autopilot whose structure is tuned (None: the log's).
    ``vehicle`` is set to the run's identity in the run folder, ``log:<log file name>``.

    Examples
    --------
    >>> LogPipelineOptions(log=Path("runs/flight.ulg"), level="quick").vehicle
    'log:flight.ulg'
    """

    log: Path = Path("flight.ulg")
    vehicle_file: str | None = None
    autopilot: str | None = None

    def __post_init__(self):
        self.vehicle = f"log:{Path(self.log).name}"


def log_settings_for(level: str) -> dict:
    """Effective settings of a log pipeline run (``full``, ``quick``, ``tiny``); part of every stage hash."""
    if level not in _LOG_LEVELS:
        raise PipelineError(f"unknown level '{level}'; valid: {', '.join(_LOG_LEVELS)}")
    return dict(_LOG_LEVELS[level], level=level)


def settings_for(level: str, n_boot: int | None = None, n_mc: int | None = None) -> dict:
    """Effective sizes and grids of a run; part of every stage hash.

    ``full`` follows the published campaign and grids; ``quick`` keeps the grids tiny but includes the
    published best settings; ``tiny`` is for tests (seconds per stage, every stage exercised).
    """
    if level not in _LEVELS:
        raise PipelineError(f"unknown level '{level}'; valid: {', '.join(LEVELS)}")
    s = dict(_LEVELS[level], level=level, controller=None)
    if n_boot is not None:
        s["n_boot"] = int(n_boot)
    if n_mc is not None:
        s["n_mc"] = int(n_mc)
    return s
