"""The options of ``datagen roles``: one frozen dataclass, the command line's and the pipeline file's."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.datagen.stage_options import not_a_param
from mimicbench.runtime.options import option


@dataclass(frozen=True)
class RolesParams:
    """``labels``: role-label files (.toml or .json; docs/roles.md), the stage's config."""

    dataset: str = not_a_param(positional=True, help="dataset folder whose characters get the labels")
    labels: tuple = option((), nargs="+", required=True, metavar="FILE",
                           help="role-label files (.toml or .json); a character may be labelled in one of them only")

    def __post_init__(self):
        object.__setattr__(self, "labels", tuple(str(f) for f in self.labels))
