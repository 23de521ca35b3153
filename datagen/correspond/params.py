"""The options of ``datagen correspond``: one frozen dataclass, the command line's and the pipeline
file's. The stage's config is what they resolve to (:func:`~mimicbench.datagen.correspond.stage.correspond_config`:
the encoder's full name, the matcher's parameters), so none of these fields is a config entry itself."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.datagen.stage_options import (engine_option, jobs_option, not_a_param, quiet_option,
                                              ray_address_option)
from mimicbench.runtime.argtypes import nonnegative_int, positive_float, positive_int

BATCH = 2048  # pairs a block (one task): Sinkhorn runs them CHUNK at a time in one padded batch


@dataclass(frozen=True)
class CorrespondParams:
    """What ``datagen correspond`` is asked (``--help`` says each; sampling: :mod:`.sampling`);
    ``block``: pairs a task (no command-line option)."""

    dataset: str = not_a_param(positional=True, help="the dataset whose characters are paired (pairs/ is added to it)")
    pairs: int | None = not_a_param(None, type=positive_int, group="pairs",
                                    help="ordered pairs to sample per split, >= 1 (default: all)")
    all_pairs: bool = not_a_param(False, group="pairs", help="every ordered pair within each split")
    unordered: bool = not_a_param(
        False, help="each pair of characters once (a->b, a's ID first): n(n-1)/2 pairs of a split of n instead of "
                    "n(n-1); PokeAnimDB's 384k pairs are C(877, 2), the unordered pairs of 90%% of 975 characters")
    pairs_across_splits: bool = not_a_param(
        False, help="also pairs between characters of different splits (cct cases made with --all-pairs use them), "
                    "sampled like a split's (--pairs, --all-pairs, --unordered), as the pair split 'across'")
    jobs: int = jobs_option("worker processes matching blocks of pairs")
    method: str = not_a_param("structure", choices=("structure", "text"),
                              help="structure (default: text and skeleton) or text (the paper's S_cos-only method)")
    no_match: float | None = not_a_param(
        None, type=float, help="structure method: score at or below which a bone stays unmatched (default 0.45)")
    encoder: str = not_a_param("minilm", choices=("minilm", "clip"), help="text encoder (default minilm, offline)")
    clip_model: str = not_a_param("ViT-B-32", help="open_clip model name (default ViT-B-32)")
    clip_pretrained: str | None = not_a_param(
        None, help="open_clip pretrained tag (downloads) or a local checkpoint file (offline)")
    temperature: float | None = not_a_param(None, type=positive_float,
                                            help="Sinkhorn temperature T, > 0 (default 0.1)")
    seed: int = not_a_param(0, type=nonnegative_int, help="pair sampling seed, >= 0 (default 0)")
    engine: str = engine_option()
    ray_address: str | None = ray_address_option()
    quiet: bool = quiet_option()
    block: int = not_a_param(BATCH, cli=False)


MIN_ADDRESS_SPACE = 1.75 * 2**30
"""Bytes of address space below which ``datagen correspond`` refuses to start: with the reservations
of :func:`mimicbench.runtime.address_space.fit_to_address_space_limit` it peaked at 1.5 GiB on a 4-character
zoo (the encoder, torch and pyarrow loaded), and at 1 GiB torch's own start aborts in C++."""


def check_address_space() -> None:
    """UserError when ``ulimit -v`` leaves less than :data:`MIN_ADDRESS_SPACE`."""
    from mimicbench.runtime.address_space import address_space_limit, limit_text
    from mimicbench.runtime.errors import UserError

    limit = address_space_limit()
    if limit is not None and limit < MIN_ADDRESS_SPACE:
        raise UserError(f"{limit_text(limit)} is below the {MIN_ADDRESS_SPACE / 2**30:.2f} GiB datagen correspond "
                        f"needs to load its text encoder, torch and pyarrow; raise it (ulimit -v "
                        f"{int(MIN_ADDRESS_SPACE) // 1024} or more) and run again")
