"""The end-to-end twin experiment: identification campaign -> identification -> bootstrap -> tuning ->
re-injection of the gains into the validation scenarios -> report (rotorlab issue 6); and the same machinery entered
from a flight log (:func:`run_log_pipeline`: identify -> calibrate -> tune -> validate -> report, issue 29).

Modules: :mod:`~rotorlab.pipeline.settings` (options, levels), :mod:`~rotorlab.pipeline.runner` (stage
hashes, manifest, atomic stage commits), :mod:`~rotorlab.pipeline.runfolder` (the run folder's layout and
typed access to its logs, models and gain sets), :mod:`~rotorlab.pipeline.models` (model and gain
conversions at 50 Hz) and :mod:`~rotorlab.pipeline.stages` (one module per stage, in run order).
"""

from rotorlab.pipeline.models import load_identified, load_plant
from rotorlab.pipeline.runfolder import RunFolder, Stage, StageContext, read_manifest, stage_dir, stage_result
from rotorlab.pipeline.runner import run_log_pipeline, run_pipeline
from rotorlab.pipeline.settings import (
                                       DT_S,
                                       FORMAT_VERSION,
                                       LogPipelineOptions,
                                       PipelineError,
                                       PipelineOptions,
                                       log_settings_for,
                                       settings_for,
)
from rotorlab.pipeline.stages import LOG_REGISTRY, LOG_STAGES, REGISTRY, STAGES
from rotorlab.pipeline.stages.validate import VALIDATION_SCENARIOS

__all__ = ["DT_S", "FORMAT_VERSION", "LOG_REGISTRY", "LOG_STAGES", "LogPipelineOptions", "REGISTRY", "STAGES",
           "VALIDATION_SCENARIOS", "PipelineError", "PipelineOptions", "RunFolder", "Stage", "StageContext",
           "load_identified", "load_plant", "read_manifest", "run_log_pipeline", "run_pipeline", "log_settings_for",
           "settings_for", "stage_dir", "stage_result"]
