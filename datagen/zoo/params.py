"""The options of ``mimicbench zoo``: one frozen dataclass, the command line's and the pipeline file's."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.datagen.stage_options import (engine_option, jobs_option, not_a_param, omitted_unless_set,
                                              quiet_option, ray_address_option)
from mimicbench.runtime.argtypes import comma_choices, int_in, nonnegative_int
from mimicbench.runtime.options import option

MAX_CHARACTERS = 100_000
MAX_CLIPS = 100
MAX_FRAMES = 10_000  # as mimicbench.datagen.zoo.motions.MAX_FRAMES (kept here so --help stays fast)
CLIP_SETS = ("default", "dynamic")  # as mimicbench.datagen.zoo.clips.CLIP_SETS
EXPORT_FORMATS = ("obj", "bvh", "pmx")


@dataclass(frozen=True)
class ZooParams:
    """What a zoo is built from (:func:`~mimicbench.datagen.zoo.dataset.build_zoo`); the fields that
    change the output are its config, after the stage's constants (generator, version, fps, H2H
    skeleton, split rule). ``categories``: a list, each item one category or several joined by commas."""

    out: str | None = not_a_param(None, required=True, folder=True, help="dataset folder to write (created if missing)")
    num_characters: int = option(40, flag="--characters", key="characters", metavar="CHARACTERS",
                                 type=int_in(1, MAX_CHARACTERS),
                                 help=f"number of characters, 1 to {MAX_CHARACTERS:,} (default 40)")
    seed: int = option(0, type=nonnegative_int, help="random seed, >= 0 (default 0)")
    categories: list | None = option(None, nargs="+", metavar="CATEGORY",
                                     help="subset of humanoid quadruped bird fish reptile insect apparel, separated by "
                                          "spaces or commas (default all)")
    clips_per_character: int = option(3, type=int_in(1, MAX_CLIPS),
                                      help=f"clips per character, 1 to {MAX_CLIPS} (default 3)")
    frames_per_clip: int = option(45, type=int_in(9, MAX_FRAMES),
                                  help=f"frames of every clip at 30 fps, 9 to {MAX_FRAMES:,} (default 45)")
    motions: int | None = omitted_unless_set(
        None, type=int_in(1, MAX_CHARACTERS * MAX_CLIPS),
        help="total clips, spread evenly over the characters (instead of --clips-per-character; at least one a "
             "character)")
    clip_set: str = omitted_unless_set(
        "default", choices=CLIP_SETS,
        help="which clips: default, or dynamic (humanoids and apparel characters spin, stop, jump and turn first, the "
             "motions where apparel lags and swings; other kinds keep their clips)")
    jobs: int = jobs_option()
    engine: str = engine_option()
    ray_address: str | None = ray_address_option()
    export: tuple = not_a_param((), type=comma_choices(EXPORT_FORMATS),
                                help="also write files: comma-separated of obj,bvh,pmx (OUT/export/<character>.obj, "
                                     "OUT/export/<character>/<clip>.bvh, OUT/export/<character>.pmx: an MMD model with "
                                     "apparel chains as rigid bodies and joints)")
    quiet: bool = quiet_option()
    no_contact_sheet: bool = not_a_param(False, help="skip rendering OUT/card/contact_sheet.png (Blender) for CARD.md")

    def __post_init__(self):
        cats = [c.strip() for arg in self.categories for c in str(arg).split(",") if c.strip()] \
            if self.categories else None
        object.__setattr__(self, "categories", cats or None)
        object.__setattr__(self, "export", tuple(self.export or ()))
