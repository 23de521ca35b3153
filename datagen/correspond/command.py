"""``mimicbench datagen correspond DATASET``: ground-truth correspondences into ``pairs/``."""
from __future__ import annotations

import argparse

from mimicbench.datagen.correspond.params import CorrespondParams, check_address_space
from mimicbench.runtime.options import add_options
from mimicbench.runtime.summary import StageSummary


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "correspond", help="bone correspondences (S_cos, Hungarian, Sinkhorn) into pairs/",
        description="Canonicalise bone names, embed them with a text encoder (MiniLM offline by default, or "
        "CLIP via open_clip), and write per character pair the cosine matrix S_cos, the Hungarian matching "
        "M_hung and the Sinkhorn soft matching M_sink into DATASET/pairs/.\n\n"
        "Methods (--method):\n"
        "  structure  (default) S_cos combined with the skeleton: sides kept, position along each chain, depth "
        "from the root,\n"
        "             limb vs trunk vs neck vs head vs tail, where a limb attaches (arm ~ front leg ~ wing), rest "
        "positions in\n"
        "             a body frame; trunks and limbs aligned as ordered sequences, never across chains. Bones "
        "scoring at most\n"
        "             --no-match (0.45) stay unmatched, except same-named or synonym ones; M_sink has a "
        "no-match dustbin.\n"
        "  text       the paper's method (MimiCAT / PokeAnimDB): S_cos only, every slot matched, M_sink balanced "
        "to rows 1.\n"
        "Each pair records its method and weights. On the zoo, prints how often matched bones share their "
        "hidden role\n(per category pair; report in DATASET/correspond_report.json). Examples:\n"
        "  mimicbench datagen correspond data/zoo --all-pairs --jobs 2\n"
        "  mimicbench datagen correspond data/zoo --all-pairs --unordered   (one direction a pair)\n"
        "  mimicbench datagen correspond data/zoo --all-pairs --pairs-across-splits   (cct pairs across splits too)\n"
        "  mimicbench datagen correspond data/zoo --pairs 20000 --method text\n"
        "  mimicbench datagen correspond data/zoo --pairs 20000 --encoder clip --clip-pretrained ~/ckpt/clip.pt",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_options(p, CorrespondParams)
    p.set_defaults(func=run)


def run(params: CorrespondParams) -> StageSummary:
    check_address_space()  # before the encoder, torch and pyarrow load
    from mimicbench.datagen.correspond.stage import run_command

    return run_command(params)
