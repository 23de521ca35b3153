"""The correspond stage: ``pairs/`` shards for a dataset (one pair on the fly: :mod:`.pair`).

The method is chosen by name (:mod:`.methods`): ``structure`` (default) or ``text`` (the paper's).
"""
from __future__ import annotations

import dataclasses
import json
import time
from collections import namedtuple
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from mimicbench.datagen.correspond.canonical import canonicalize_names
from mimicbench.datagen.correspond.encoders import get_encoder
from mimicbench.datagen.correspond.methods import DEFAULT_METHOD, get_matcher, match_batch, skeleton_feature_table
from mimicbench.datagen.correspond.report import format_report, role_agreement_report
from mimicbench.datagen.correspond.sampling import INTRA_FRACTION, sample_pairs
from mimicbench.datagen.stage_runner import Stage, StageRun, omitted_unless_set, run_stage
from mimicbench.engines import Engine, TaskResources
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.manifest import atomic_write_bytes
from mimicbench.schemas.pair import PairRecord
from mimicbench.schemas.shards import read_records, remove_split, splits_of
from mimicbench.schemas.tables import rows_per_shard

_Matched = namedtuple("_Matched", "source_id target_id hungarian")  # what the role-agreement report reads of a pair
ACROSS = "across"  # the pair split of pairs between characters of different splits
BATCH = 2048  # pairs a block (one task): Sinkhorn runs them CHUNK at a time in one padded batch
ROWS_PER_SHARD = rows_per_shard("pairs", "correspond")  # memory holds one shard's matrices while writing
TASK_RESOURCES = TaskResources(num_cpus=1, memory=1 << 30)


def embed_skeletons(records, encoder) -> dict[str, np.ndarray]:
    """Per character ID its (K, d) unit embeddings; each unique canonical name is embedded once."""
    canon = {r.character_id: canonicalize_names(r.bone_names) for r in records}
    unique = sorted({t for names in canon.values() for t in names})
    table = dict(zip(unique, encoder.embed(unique))) if unique else {}
    return {cid: np.stack([table[t] for t in names]) for cid, names in canon.items() if names}


def _match_block(ids: list[tuple[str, str]], method, emb: dict, feats: dict) -> list[tuple]:
    """(S_cos, M_hung pairs, M_sink) of a block of (source ID, target ID) pairs, batched (one task)."""
    return match_batch(method, [emb[a] for a, _ in ids], [emb[b] for _, b in ids],
                       [feats[a] for a, _ in ids] if feats else None, [feats[b] for _, b in ids] if feats else None)


@dataclass(frozen=True)
class CorrespondParams:
    """The arguments of :func:`correspond_dataset` (``method``: the matcher's params; sampling: :mod:`.sampling`)."""

    encoder: str
    temperature: float
    seed: int
    pairs: int | None
    all_pairs: bool
    intra_fraction: float
    method: dict
    unordered: bool = omitted_unless_set(False)
    across_splits: bool = omitted_unless_set(False)


STAGE = Stage("correspond", CorrespondParams, inputs=("characters",), item=_match_block, outputs=("pairs", "status"))


def pair_blocks(chosen: list[tuple], rows_per_shard: int = ROWS_PER_SHARD,
                batch: int = BATCH) -> tuple[list[list[int]], set[int]]:
    """Blocks of indices into ``chosen`` (ordered pairs of records), one task each, and the
    numbers of the blocks that end a shard-sized run.

    Pairs are cut into runs of ``rows_per_shard`` in their sampled order; within a run they are
    sorted by (K1, K2) so a block pads little, then cut into blocks of ``batch`` pairs. The blocks
    of a run come before those of the next, so a run is complete (and its shard written) once its
    last block is in.
    """
    blocks, ends = [], set()
    for s0 in range(0, len(chosen), rows_per_shard):
        run = sorted(range(s0, min(s0 + rows_per_shard, len(chosen))),
                     key=lambda i: (chosen[i][0].num_joints, chosen[i][1].num_joints))
        blocks += [run[b:b + batch] for b in range(0, len(run), batch)]
        ends.add(len(blocks) - 1)
    return blocks, ends


def correspond_dataset(dataset_dir, pairs: int | None = None, all_pairs: bool = False, encoder: str = "minilm",
                       temperature: float | None = None, seed: int = 0, clip_model: str = "ViT-B-32",
                       clip_pretrained: str | None = None, progress: bool = True, method: str = DEFAULT_METHOD,
                       no_match: float | None = None, engine: Engine | None = None, block: int = BATCH,
                       unordered: bool = False, across_splits: bool = False) -> dict:
    """Write ``pairs/`` shards (one group per split) and ``correspond_report.json``; return a summary.

    Args:
        dataset_dir: dataset folder with a ``characters`` table.
        pairs, all_pairs, unordered: ordered pairs per split to sample (None: all), or every
            ordered pair, or each pair of characters once (a->b with a's ID first): :mod:`.sampling`.
        encoder: ``minilm`` (offline default) or ``clip``.
        method: ``structure`` (default: text and skeleton, ``no_match`` threshold, default 0.45) or
            ``text`` (the paper's S_cos, Hungarian, Sinkhorn): :mod:`mimicbench.datagen.correspond.methods`.
        temperature: Sinkhorn temperature T on the scores (default 0.1); seed: pair sampling seed.
        across_splits: also the pairs between characters of different splits, sampled like a
            split's and written as the pair split :data:`ACROSS`; without it an earlier run's are removed.
        engine, block: where blocks of ``block`` pairs (one task each) are matched (default this
            process); shards of ``ROWS_PER_SHARD`` pairs are written in sampled order as their
            blocks come in, so memory holds one shard and the bytes do not depend on the engine.
    """
    start = time.perf_counter()
    dataset_dir = Path(dataset_dir)
    records = [r for r in read_records(dataset_dir, "characters") if r.num_joints > 0]  # DatasetError if no dataset
    if not records:
        raise DatasetError(f"{dataset_dir}: no character with bones in the characters table; nothing to correspond")
    by_id = {r.character_id: r for r in records}
    m = get_matcher(method, temperature, no_match)
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    emb = embed_skeletons(records, enc)
    feats = skeleton_feature_table(records) if m.uses_structure else {}
    params = json.loads(m.params_json())
    written, matched, statuses = {}, [], []
    stage_run = StageRun(STAGE, CorrespondParams(enc.name, m.temperature, seed, pairs, all_pairs, INTRA_FRACTION, params,
                                           bool(unordered), bool(across_splits)),
                         dataset_dir, dataset_dir, refuse_foreign=False)  # adds pairs to its input
    fn = partial(STAGE.item, method=m, emb=emb, feats=feats)
    groups = [(split, sample_pairs([r for r in records if r.split == split], pairs, all_pairs, seed, unordered))
              for split in splits_of(dataset_dir, "characters")]
    if across_splits:
        groups.append((ACROSS, sample_pairs(records, pairs, all_pairs, seed, unordered,
                                            keep=lambda a, b: a.split != b.split)))
    elif ACROSS in splits_of(dataset_dir, "pairs", allow_incomplete=True):  # a previous run's
        remove_split(dataset_dir, "pairs", ACROSS)
    for split, chosen in groups:
        blocks, ends = pair_blocks(chosen, ROWS_PER_SHARD, block)
        run: dict[int, PairRecord] = {}
        written[split] = 0
        with stage_run.streams([("pairs", split)]) as streams:

            def on_done(k: int, ok: bool, mats) -> None:  # called by run_stage below, in this iteration
                for i, (s, h, sink) in zip(blocks[k], mats if ok else ()):  # a failed block's pairs are left out
                    a, b = chosen[i]
                    run[i] = PairRecord(f"{a.character_id}->{b.character_id}", a.character_id, b.character_id, split,
                                        a.num_joints, b.num_joints, s, h, sink, enc.name, float(m.temperature),
                                        a.category, b.category, m.name, params)
                if k in ends:
                    rows = [run.pop(i) for i in sorted(run)]
                    streams["pairs", split].add(rows)
                    matched.extend(_Matched(p.source_id, p.target_id, p.hungarian) for p in rows)
                    written[split] += len(rows)

            items = [[(chosen[i][0].character_id, chosen[i][1].character_id) for i in blk] for blk in blocks]
            _, block_statuses = run_stage(items, fn, f"correspond/{split}", progress=progress, on_done=on_done,
                                          name_of=lambda ids: f"{split} block {ids[0][0]}->{ids[0][1]} "
                                                              f"(+{len(ids) - 1} pairs)",
                                          engine=engine, ordered=True, keep_results=False, resources=TASK_RESOURCES)
        statuses += [dataclasses.replace(st, stage="correspond", seconds=0.0) for st in block_statuses
                     if st.status != "ok"]
    if statuses:  # blocks whose task failed for good (e.g. its worker died on every retry)
        stage_run.write_status(statuses, config=None)  # the status table's config stays its maker's
    else:
        remove_split(dataset_dir, "status", "correspond")
    report = role_agreement_report(by_id, matched, params)
    atomic_write_bytes(dataset_dir / "correspond_report.json", (json.dumps(report, indent=2) + "\n").encode())
    if progress:
        print(format_report(report))
    return {"pairs": written, "failed_blocks": [f"{st.asset}: {st.reason}" for st in statuses],
            "encoder": enc.name, "method": m.name, "temperature": m.temperature, "report": report,
            "seconds": time.perf_counter() - start}
