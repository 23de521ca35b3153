"""The options of ``datagen resample``: one dataclass, the command line's and the pipeline file's."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.datagen.resample import MAX_FACES, MIN_FACES
from mimicbench.datagen.stage_options import engine_option, jobs_option, not_a_param, quiet_option, ray_address_option
from mimicbench.runtime.argtypes import int_in
from mimicbench.runtime.options import option

BACKENDS = ("fast", "pymeshlab")


@dataclass(frozen=True)
class ResampleParams:
    """The options of ``datagen resample`` (the command line's and the pipeline file's)."""

    in_dataset: str = not_a_param(positional=True, key="in", help="the dataset whose characters are resampled")
    out_dataset: str = not_a_param(positional=True, key="out", help="the output dataset folder")
    faces: int = option(5000, type=int_in(MIN_FACES, MAX_FACES),
                        help=f"target face count, {MIN_FACES} to {MAX_FACES:,} (default 5000)")
    backend: str = option("fast", choices=BACKENDS,
                          help="fast (fast-simplification, default) or pymeshlab (MeshLab's quadric edge collapse)")
    jobs: int = jobs_option()
    engine: str = engine_option()
    ray_address: str | None = ray_address_option()
    quiet: bool = quiet_option()
