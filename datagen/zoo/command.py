"""``mimicbench zoo``: generate the procedural character zoo."""
from __future__ import annotations

import argparse

from mimicbench.engines import add_engine_arguments
from mimicbench.runtime.summary import StageSummary
from mimicbench.runtime.argtypes import MAX_JOBS, comma_choices, int_in, job_count, nonnegative_int

MAX_CHARACTERS = 100_000
MAX_CLIPS = 100
MAX_FRAMES = 10_000  # as mimicbench.datagen.zoo.motions.MAX_FRAMES (kept here so --help stays fast)
CLIP_SETS = ("default", "dynamic")  # as mimicbench.datagen.zoo.clips.CLIP_SETS

DESCRIPTION = """\
Generate procedural rigged, skinned and animated characters of every kind (humanoid, quadruped,
bird, fish, reptile or snake, insect or spider, humanoid with apparel chains), with bone names
in real assets' styles, hidden semantic bone roles, an H2H family of humanoids sharing one
skeleton, and procedural clips (gaits, flaps, swims, slithers, idles, random poses) at 30 fps.
The output is deterministic for a seed: the same command gives byte-identical shards.

example:
  mimicbench zoo --out data/zoo --characters 40 --seed 0
  mimicbench zoo --out data/fish --characters 5 --categories fish,reptile --export obj,bvh
  mimicbench zoo --out data/app --characters 100 --categories apparel --clip-set dynamic --clips-per-character 4
  mimicbench validate data/zoo
  mimicbench zoo --out data/pokeanimdb --characters 975 --motions 28809 --frames-per-clip 155 --jobs 2
      (PokeAnimDB's Table 1 shape: 975 characters, 28,809 clips, 4.47M frames, 11-241 joints)
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("zoo", help="generate procedural rigged, animated characters (the offline default dataset)",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="dataset folder to write (created if missing)")
    p.add_argument("--characters", type=int_in(1, MAX_CHARACTERS), default=40,
                   help=f"number of characters, 1 to {MAX_CHARACTERS:,} (default 40)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed, >= 0 (default 0)")
    p.add_argument("--categories", nargs="+", default=None, metavar="CATEGORY",
                   help="subset of humanoid quadruped bird fish reptile insect apparel, separated by spaces or "
                   "commas (default all)")
    p.add_argument("--clips-per-character", type=int_in(1, MAX_CLIPS), default=3,
                   help=f"clips per character, 1 to {MAX_CLIPS} (default 3)")
    p.add_argument("--motions", type=int_in(1, MAX_CHARACTERS * MAX_CLIPS), default=None,
                   help="total clips, spread evenly over the characters (instead of --clips-per-character; at least "
                        "one a character)")
    p.add_argument("--frames-per-clip", type=int_in(9, MAX_FRAMES), default=45,
                   help=f"frames of every clip at 30 fps, 9 to {MAX_FRAMES:,} (default 45)")
    p.add_argument("--clip-set", choices=CLIP_SETS, default="default",
                   help="which clips: default, or dynamic (humanoids and apparel characters spin, stop, jump and turn "
                        "first, the motions where apparel lags and swings; other kinds keep their clips)")
    p.add_argument("--jobs", type=job_count, default=1, help=f"worker processes, 1 to {MAX_JOBS} (default 1)")
    add_engine_arguments(p)
    p.add_argument("--export", type=comma_choices(("obj", "bvh", "pmx")), default=(),
                   help="also write files: comma-separated of obj,bvh,pmx "
                   "(OUT/export/<character>.obj, OUT/export/<character>/<clip>.bvh, OUT/export/<character>.pmx: "
                   "an MMD model with apparel chains as rigid bodies and joints)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--no-contact-sheet", action="store_true",
                   help="skip rendering OUT/card/contact_sheet.png (Blender) for CARD.md")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mimicbench.engines import engine_from_args
    from mimicbench.datagen.zoo.dataset import build_zoo

    cats = [c.strip() for arg in args.categories for c in arg.split(",") if c.strip()] if args.categories else None
    s = build_zoo(args.out, args.characters, seed=args.seed, categories=cats,
                  clips_per_character=args.clips_per_character, export=tuple(args.export), progress=not args.quiet,
                  motions=args.motions, frames_per_clip=args.frames_per_clip, engine=engine_from_args(args),
                  clip_set=args.clip_set)
    for f in s["failures"]:
        print(f"  FAILED {f}")
    if not args.no_contact_sheet:
        from mimicbench.datagen.zoo.card import add_contact_sheet

        sheet = add_contact_sheet(args.out)
        print(f"contact sheet: {sheet['path'] or 'not rendered: ' + sheet['error']}")
    cats_txt = ", ".join(f"{k} {v}" for k, v in s["by_category"].items())
    print(f"zoo: {s['characters']} characters ({cats_txt}), {s['motions']} clips, {s['frames']} frames; "
          f"joints {s['joints'][0]}-{s['joints'][2]}, faces {s['faces'][0]}-{s['faces'][2]}; "
          f"H2H family {s['h2h_family']}; splits {s['splits']}; {s['failed']} failed; "
          f"{s['seconds']:.1f} s -> {s['out']} (see CARD.md)")
    return StageSummary(s["characters"], s["failed"], s["seconds"], str(args.out))
