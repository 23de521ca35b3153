"""``mimicbench datagen correspond DATASET``: ground-truth correspondences into ``pairs/``."""
from __future__ import annotations

import argparse

from mimicbench.engines import add_engine_arguments
from mimicbench.runtime.summary import StageSummary
from mimicbench.runtime.argtypes import MAX_JOBS, job_count, nonnegative_int, positive_float, positive_int


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
    p.add_argument("dataset")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--pairs", type=positive_int, default=None,
                   help="ordered pairs to sample per split, >= 1 (default: all)")
    g.add_argument("--all-pairs", action="store_true", help="every ordered pair within each split")
    p.add_argument("--unordered", action="store_true",
                   help="each pair of characters once (a->b, a's ID first): n(n-1)/2 pairs of a split of n instead of "
                        "n(n-1); PokeAnimDB's 384k pairs are C(877, 2), the unordered pairs of 90%% of 975 characters")
    p.add_argument("--pairs-across-splits", action="store_true",
                   help="also pairs between characters of different splits (cct cases made with --all-pairs use them), "
                        "sampled like a split's (--pairs, --all-pairs, --unordered), as the pair split 'across'")
    p.add_argument("--jobs", type=job_count, default=1,
                   help=f"worker processes matching blocks of pairs, 1 to {MAX_JOBS} (default 1; each on one thread)")
    p.add_argument("--method", choices=("structure", "text"), default="structure",
                   help="structure (default: text and skeleton) or text (the paper's S_cos-only method)")
    p.add_argument("--no-match", type=float, default=None,
                   help="structure method: score at or below which a bone stays unmatched (default 0.45)")
    p.add_argument("--encoder", choices=("minilm", "clip"), default="minilm")
    p.add_argument("--clip-model", default="ViT-B-32", help="open_clip model name (default ViT-B-32)")
    p.add_argument("--clip-pretrained", default=None,
                   help="open_clip pretrained tag (downloads) or a local checkpoint file (offline)")
    p.add_argument("--temperature", type=positive_float, default=None,
                   help="Sinkhorn temperature T, > 0 (default 0.1)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="pair sampling seed, >= 0 (default 0)")
    add_engine_arguments(p)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


MIN_ADDRESS_SPACE = 1.75 * 2**30
"""Bytes of address space below which ``datagen correspond`` refuses to start: with the reservations
of :func:`mimicbench.runtime.address_space.fit_to_address_space_limit` it peaked at 1.5 GiB on a 4-character
zoo (the encoder, torch and pyarrow loaded), and at 1 GiB torch's own start aborts in C++."""


def run(args) -> int:
    from mimicbench.runtime.address_space import address_space_limit, limit_text
    from mimicbench.runtime.errors import UserError

    limit = address_space_limit()
    if limit is not None and limit < MIN_ADDRESS_SPACE:
        raise UserError(f"{limit_text(limit)} is below the {MIN_ADDRESS_SPACE / 2**30:.2f} GiB datagen correspond "
                        f"needs to load its text encoder, torch and pyarrow; raise it (ulimit -v "
                        f"{int(MIN_ADDRESS_SPACE) // 1024} or more) and run again")
    return _run(args)


def _run(args) -> int:
    from mimicbench.datagen.correspond.stage import correspond_dataset
    from mimicbench.engines import engine_from_args

    summary = correspond_dataset(args.dataset, args.pairs, args.all_pairs, args.encoder, args.temperature, args.seed,
                                 args.clip_model, args.clip_pretrained, progress=not args.quiet, method=args.method,
                                 no_match=args.no_match, engine=engine_from_args(args), unordered=args.unordered,
                                 across_splits=args.pairs_across_splits)
    for failure in summary["failed_blocks"]:
        print(f"  FAILED {failure}")
    print(f"pairs written: {summary['pairs']} with {summary['encoder']}, method {summary['method']}, in "
          f"{summary['seconds']:.1f} s (report: {args.dataset}/correspond_report.json)")
    return StageSummary(sum(summary["pairs"].values()), len(summary["failed_blocks"]), summary["seconds"],
                        str(args.dataset))
