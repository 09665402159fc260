"""The pipeline's stages, one module each, in run order. A module declares ``STAGE``
(:class:`rotorlab.pipeline.runfolder.Stage`: name, upstream stages, the settings it depends on, its function);
a new stage is one new module plus its entry in :data:`REGISTRY`."""

from rotorlab.pipeline.runfolder import Stage
from rotorlab.pipeline.stages import bootstrap, experiments, greybox, identify, report, tune, validate

__all__ = ["REGISTRY", "STAGES"]

REGISTRY: dict[str, Stage] = {m.STAGE.name: m.STAGE
                              for m in (experiments, identify, greybox, bootstrap, tune, validate, report)}
STAGES = tuple(REGISTRY)
