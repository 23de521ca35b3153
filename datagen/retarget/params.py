"""The options of ``datagen retarget``: one frozen dataclass, the command line's and the pipeline file's."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.datagen.stage_options import not_a_param, quiet_option
from mimicbench.runtime.options import option


@dataclass(frozen=True)
class RetargetParams:
    """sources, targets: globs on the source and target character IDs (the stage's config)."""

    motions: str = not_a_param(positional=True, help="dataset whose clips are retargeted (its characters and motions)")
    characters: str = not_a_param(positional=True, help="dataset whose characters receive the clips")
    out: str = not_a_param(positional=True, help="output dataset folder")
    sources: str = option("*", help="glob on source character IDs (default: all)")
    targets: str = option("*", help="glob on target character IDs (default: all)")
    quiet: bool = quiet_option()
