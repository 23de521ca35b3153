"""Every datagen stage by name: its :class:`~mimicbench.datagen.stage_runner.Stage` declaration
(params, tables, items, command), imported on first use. The pipeline's step kinds of the datagen
stages come from here."""
from __future__ import annotations

from mimicbench.runtime.registry import Registry

STAGES = Registry("stage", {
    "apparel": "mimicbench.datagen.apparel.stage:STAGE",
    "correspond": "mimicbench.datagen.correspond.stage:STAGE",
    "ingest": "mimicbench.datagen.ingest.runner:STAGE",
    "resample": "mimicbench.datagen.resample.stage:STAGE",
    "retarget": "mimicbench.datagen.retarget.stage:STAGE",
    "roles": "mimicbench.datagen.roles.attach:STAGE_DECL",
    "zoo": "mimicbench.datagen.zoo.dataset:STAGE",
})
"""Stage name -> its :class:`~mimicbench.datagen.stage_runner.Stage`."""

__all__ = ["STAGES"]
