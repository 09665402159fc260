"""The pipelines' stages, one module each, in run order: the twin pipeline's (:data:`REGISTRY`) and the log
pipeline's (:data:`LOG_REGISTRY`, modules ``log_*``). A module declares ``STAGE``
(:class:`rotorlab.pipeline.runfolder.Stage`: name, upstream stages, the settings it depends on, its function);
a new stage is one new module plus its entry in its registry."""

from rotorlab.pipeline.runfolder import Stage
from rotorlab.pipeline.stages import (
    bootstrap,
    experiments,
    greybox,
    identify,
    log_calibrate,
    log_identify,
    log_report,
    log_tune,
    log_validate,
    report,
    tune,
    validate,
)

__all__ = ["REGISTRY", "STAGES", "LOG_REGISTRY", "LOG_STAGES"]

REGISTRY: dict[str, Stage] = {m.STAGE.name: m.STAGE
                              for m in (experiments, identify, greybox, bootstrap, tune, validate, report)}
STAGES = tuple(REGISTRY)

#: the log pipeline (``rotorlab pipeline --log``): the same machinery entered from a flight log
LOG_REGISTRY: dict[str, Stage] = {m.STAGE.name: m.STAGE
                                  for m in (log_identify, log_calibrate, log_tune, log_validate, log_report)}
LOG_STAGES = tuple(LOG_REGISTRY)
