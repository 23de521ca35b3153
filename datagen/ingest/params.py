"""The options of ``datagen ingest``: one frozen dataclass, the command line's and the pipeline
file's (:mod:`mimicbench.runtime.options`); :meth:`IngestParams.check` says what is allowed."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from mimicbench.datagen.ingest.clip_length import MAX_CLIP_FRAMES
from mimicbench.datagen.mmd.frame import MMD_UNIT_METRES
from mimicbench.datagen.stage_options import engine_option, jobs_option, not_a_param, quiet_option, ray_address_option
from mimicbench.runtime.argtypes import MAX_JOBS, comma_choices, positive_float, positive_int
from mimicbench.runtime.options import option

EXPORT_FORMATS = ("obj", "bvh")
DEFAULT_BVH_SCALE = "auto"  # metres per BVH unit from the rest skeleton (datagen/ingest/bvh_units.py)


def bvh_scale_arg(text: str) -> float | str:
    """``--bvh-scale``: ``auto`` or metres per file unit greater than 0."""
    return "auto" if text == "auto" else positive_float(text)


def _positive(x) -> bool:
    """A finite number > 0 (not a bool)."""
    return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x) and x > 0


@dataclass(frozen=True)
class IngestParams:
    """What ``datagen ingest`` may be asked (``--help`` says each). ``category_map``: a JSON file
    (or, from Python, the mapping itself) of glob or file stem -> category; ``assets_per_process``:
    assets before a fresh Blender (no command-line option)."""

    paths: tuple = not_a_param((), positional=True, nargs="+",
                               help="asset files, folders (walked for asset files) or glob patterns")
    out: str | None = not_a_param(None, required=True, folder=True, help="dataset folder (created, or added to)")
    jobs: int = jobs_option("Blender processes at once")
    timeout: float = option(300.0, type=positive_float,
                            help="seconds per asset before its Blender process is killed, > 0 (default 300)")
    category_map: str | dict | None = option(
        None, help="JSON file mapping a glob or file stem to a category; assets it does not name get an inferred "
                   "category")
    bvh_scale: float | str = option(
        DEFAULT_BVH_SCALE, type=bvh_scale_arg,
        help="metres per BVH file unit, > 0, or 'auto' (default): the first of centimetres, metres, CMU units "
             "(0.056444), inches, millimetres that makes the rest skeleton 0.3-3 m tall; the choice is recorded in "
             "each character's meta")
    mmd_unit: float = option(
        MMD_UNIT_METRES, type=positive_float, metavar="METRES",
        help="metres per MMD unit for .pmx/.pmd/.vmd files, > 0 (default 0.08, the scale of mmd_tools and of MMD "
             "players); recorded in each MMD character's meta.mmd.metres_per_unit")
    mesh_unit: float = option(
        1.0, type=positive_float, metavar="METRES",
        help="metres per unit of the scene Blender imports from .glb/.gltf/.fbx/.obj/.blend, > 0 (default 1: glTF "
             "is in metres and Blender converts FBX units); every length is multiplied by it (0.01 for a file "
             "authored in centimetres but declared in metres); a character under 0.05 m or over 30 m across gets a "
             "warning; recorded in meta.ingest")
    export: tuple = not_a_param((), type=comma_choices(EXPORT_FORMATS),
                                help="comma-separated of obj,bvh: also write OUT/export/ files")
    split: str | None = option(None, choices=("train", "val", "test"), group="split",
                               help="put every asset of this run in one split (default: a hash of the character ID)")
    split_file: str | None = option(None, group="split",
                                    help="JSON mapping split name to a list of character IDs (others: hashed split)")
    allow_external_uris: bool = option(
        False, help="let glTF buffers and images point outside the asset's folder (refused by default)")
    max_clip_frames: int = option(
        MAX_CLIP_FRAMES, type=positive_int, metavar="N",
        help=f"the most frames a clip may have, checked before it is sampled, for every format (default "
             f"{MAX_CLIP_FRAMES}: 20 minutes at 30 fps); a longer clip becomes a failed status row")
    motions: str | None = not_a_param(
        None, metavar="DIR",
        help="folder of .vmd motions to play on every MMD model of the run (besides <stem>_<clip>.vmd)")
    roles: tuple | None = not_a_param(
        None, nargs="+", metavar="FILE",
        help="role-label files (.toml/.json, docs/roles.md) attached after the ingest, as `mimicbench datagen roles "
             "OUT --labels FILE` does: hidden bone roles and categories")
    engine: str = engine_option()
    ray_address: str | None = ray_address_option()
    quiet: bool = quiet_option()
    assets_per_process: int = not_a_param(50, cli=False)

    def __post_init__(self):
        object.__setattr__(self, "paths", tuple(str(p) for p in self.paths))
        object.__setattr__(self, "export", tuple(self.export))

    def check(self) -> None:
        """Raise ValueError naming the option and the allowed range."""
        from mimicbench.geometry.validation import expect, is_whole
        from mimicbench.schemas.character import CATEGORIES

        expect(isinstance(self.jobs, int) and 1 <= self.jobs <= MAX_JOBS, "--jobs",
               f"a whole number of Blender processes from 1 to {MAX_JOBS}", self.jobs)
        expect(self.timeout > 0, "--timeout", "seconds per asset greater than 0", self.timeout)
        expect(self.bvh_scale == "auto" or (isinstance(self.bvh_scale, (int, float)) and self.bvh_scale > 0),
               "--bvh-scale", "'auto' or metres per BVH unit greater than 0 (0.01 for centimetres)", self.bvh_scale)
        expect(_positive(self.mmd_unit), "--mmd-unit",
               "metres per MMD unit, a finite number greater than 0 (MMD's usual 0.08)", self.mmd_unit)
        expect(_positive(self.mesh_unit), "--mesh-unit", "metres per unit of the imported scene, a finite number "
               "greater than 0 (1: glTF's metres; 0.01 for a file authored in centimetres)", self.mesh_unit)
        expect(is_whole(self.max_clip_frames) and self.max_clip_frames >= 1, "--max-clip-frames",
               f"a whole number of frames of at least 1 (default {MAX_CLIP_FRAMES})", self.max_clip_frames)
        expect(isinstance(self.assets_per_process, int) and self.assets_per_process >= 1, "assets_per_process",
               "at least 1", self.assets_per_process)
        unknown = [x for x in self.export if x not in EXPORT_FORMATS]
        expect(not unknown, "--export", f"a comma-separated list of {', '.join(EXPORT_FORMATS)}", unknown)
        bad = {k: v for k, v in self.categories().items() if v not in CATEGORIES}
        expect(not bad, "--category-map", f"categories of {', '.join(CATEGORIES)}", bad)
        expect(self.split is None or self.split_file is None, "--split and --split-file", "one of them, not both",
               self.split_file)
        expect(self.split in (None, "train", "val", "test"), "--split", "train, val or test", self.split)
        if self.motions and not Path(self.motions).is_dir():
            raise NotADirectoryError(f"--motions: {self.motions} is not a folder of .vmd files")

    def categories(self) -> dict:
        """The category map: ``category_map`` itself, or the JSON file it names ({} when None)."""
        if isinstance(self.category_map, (str, Path)):
            import json

            return dict(json.loads(Path(self.category_map).read_text()))
        return dict(self.category_map or {})

    def child_options(self, asset: Path) -> dict:
        """The options that change what a child writes for ``asset`` (part of its cache key); the
        clip length bound only when it is not the default (so default cache keys stay as they were)."""
        out = {"bvh_scale": self.bvh_scale_for(asset)[0]} if asset.suffix.lower() == ".bvh" else {}
        if self.max_clip_frames != MAX_CLIP_FRAMES:
            out["max_clip_frames"] = int(self.max_clip_frames)
        return out

    def bvh_scale_for(self, asset: Path) -> tuple[float, dict]:
        """Metres per unit of the BVH file ``asset`` and how it was chosen (``--bvh-scale``)."""
        from mimicbench.datagen.ingest.bvh_units import auto_bvh_scale, bvh_rest_height

        if self.bvh_scale != "auto":
            return float(self.bvh_scale), {"bvh_scale_source": "--bvh-scale"}
        height = bvh_rest_height(asset)
        scale, unit, plausible = auto_bvh_scale(height)
        return scale, {"bvh_scale_source": "auto", "bvh_unit": unit, "bvh_rest_height_units": round(height, 4),
                       "bvh_unit_plausible": plausible}
