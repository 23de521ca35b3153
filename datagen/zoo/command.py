"""``mimicbench zoo``: generate the procedural character zoo."""
from __future__ import annotations

import argparse

from mimicbench.datagen.zoo.params import MAX_CHARACTERS, MAX_CLIPS, MAX_FRAMES, ZooParams  # noqa: F401
from mimicbench.runtime.options import add_options
from mimicbench.runtime.summary import StageSummary

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
    add_options(p, ZooParams)
    p.set_defaults(func=run)


def run(params: ZooParams) -> StageSummary:
    from mimicbench.datagen.zoo.dataset import run_command

    return run_command(params)
