"""The correspond stage: ``pairs/`` shards for a dataset (one pair on the fly: :mod:`.pair`).

The method is chosen by name (:mod:`.methods`): ``structure`` (default) or ``text`` (the paper's).
"""
from __future__ import annotations

import dataclasses
import json
from collections import namedtuple

import numpy as np

from mimicbench.datagen.correspond.canonical import canonicalize_names
from mimicbench.datagen.correspond.encoders import get_encoder
from mimicbench.datagen.correspond.methods import DEFAULT_METHOD, get_matcher, match_batch, skeleton_feature_table
from mimicbench.datagen.correspond.report import format_report, role_agreement_report
from mimicbench.datagen.correspond.sampling import INTRA_FRACTION, sample_pairs
from mimicbench.datagen.correspond.params import BATCH, CorrespondParams, check_address_space
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.engines import Engine, TaskResources
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.manifest import atomic_write_bytes
from mimicbench.schemas.pair import PairRecord
from mimicbench.schemas.shards import read_records, splits_of
from mimicbench.schemas.tables import rows_per_shard

_Matched = namedtuple("_Matched", "source_id target_id hungarian")  # what the role-agreement report reads of a pair
ACROSS = "across"  # the pair split of pairs between characters of different splits
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


def correspond_config(params: CorrespondParams) -> dict:
    """The config of a run: the encoder's full name, the Sinkhorn temperature and the matcher's
    parameters it resolves to, the sampling (``unordered``/``across_splits`` only when set, so
    older configs keep their fingerprint)."""
    m = get_matcher(params.method, params.temperature, params.no_match)
    enc = get_encoder(params.encoder, params.clip_model, params.clip_pretrained)
    config = {"encoder": enc.name, "temperature": m.temperature, "seed": params.seed, "pairs": params.pairs,
              "all_pairs": params.all_pairs, "intra_fraction": INTRA_FRACTION, "method": json.loads(m.params_json())}
    return {**config, **({"unordered": True} if params.unordered else {}),
            **({"across_splits": True} if params.pairs_across_splits else {})}


class CorrespondPlan(StagePlan):
    """Per split (and :data:`ACROSS`), the sampled pairs in blocks of ``block`` pairs (one task
    each); shards of ``ROWS_PER_SHARD`` pairs are written in sampled order as their blocks come in
    (:meth:`done`), so memory holds one shard and the bytes do not depend on the engine."""

    ordered = True
    resources = TASK_RESOURCES
    status_config = None  # the status table's config stays its maker's

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        p, dataset_dir = run.params, run.out_dir
        self.records = [r for r in read_records(dataset_dir, "characters", allow_incomplete=run.resuming)
                        if r.num_joints > 0]
        if not self.records:
            raise DatasetError(f"{dataset_dir}: no character with bones in the characters table; nothing to correspond")
        self.m = get_matcher(p.method, p.temperature, p.no_match)
        self.enc = get_encoder(p.encoder, p.clip_model, p.clip_pretrained)
        emb = embed_skeletons(self.records, self.enc)
        feats = skeleton_feature_table(self.records) if self.m.uses_structure else {}
        self.params = json.loads(self.m.params_json())
        self.kwargs = {"method": self.m, "emb": emb, "feats": feats}
        self.groups = [(split, sample_pairs([r for r in self.records if r.split == split], p.pairs, p.all_pairs,
                                            p.seed, p.unordered))
                       for split in splits_of(dataset_dir, "characters", allow_incomplete=run.resuming)]
        if p.pairs_across_splits:
            self.groups.append((ACROSS, sample_pairs(self.records, p.pairs, p.all_pairs, p.seed, p.unordered,
                                                     keep=lambda a, b: a.split != b.split)))
        elif ACROSS in splits_of(dataset_dir, "pairs", allow_incomplete=True):  # a previous run's
            self.drop.append(("pairs", ACROSS))
        self.block, self.written, self.matched, self.run = p.block, {}, [], run

    def name_of(self, ids) -> str:
        return f"{self.split} block {ids[0][0]}->{ids[0][1]} (+{len(ids) - 1} pairs)"

    def batches(self):
        for split, chosen in self.groups:
            self.split, self.chosen = split, chosen
            self.blocks, self.ends = pair_blocks(chosen, ROWS_PER_SHARD, self.block)
            self.pending, self.written[split] = {}, 0
            self.next_block = 0
            self.stream = self.run.open_streams([("pairs", split)])["pairs", split]
            yield f"correspond/{split}", [[(chosen[i][0].character_id, chosen[i][1].character_id) for i in blk]
                                          for blk in self.blocks]
            self.stream.close()
            self.stream = None

    def done(self, run, ids, ok, mats) -> None:
        k, self.next_block = self.next_block, self.next_block + 1  # ordered: blocks come in their order
        chosen, m, enc = self.chosen, self.m, self.enc
        for i, (s, h, sink) in zip(self.blocks[k], mats if ok else ()):  # a failed block's pairs are left out
            a, b = chosen[i]
            self.pending[i] = PairRecord(f"{a.character_id}->{b.character_id}", a.character_id, b.character_id,
                                         self.split, a.num_joints, b.num_joints, s, h, sink, enc.name,
                                         float(m.temperature), a.category, b.category, m.name, self.params)
        if k in self.ends:
            rows = [self.pending.pop(i) for i in sorted(self.pending)]
            self.stream.add(rows)
            self.matched.extend(_Matched(p.source_id, p.target_id, p.hungarian) for p in rows)
            self.written[self.split] += len(rows)

    def abort(self, run, exc) -> None:
        if getattr(self, "stream", None) is not None:
            self.stream.abort()

    def nothing_made(self, statuses) -> bool:
        return False  # the failed blocks are status rows; the pairs of the others are written

    def write(self, run, statuses):
        failed = [dataclasses.replace(st, stage="correspond", seconds=0.0) for st in statuses if st.status != "ok"]
        self.failed = failed
        self.reported = failed
        self.details = {"pairs": self.written, "failed_blocks": [f"{st.asset}: {st.reason}" for st in failed],
                        "encoder": self.enc.name, "method": self.m.name, "temperature": self.m.temperature}
        return failed or None, self.details

    def after(self, run) -> None:
        self.report = role_agreement_report({r.character_id: r for r in self.records}, self.matched, self.params)
        atomic_write_bytes(run.out_dir / "correspond_report.json", (json.dumps(self.report, indent=2) + "\n").encode())
        self.details["report"] = self.report
        if not run.params.quiet:
            print(format_report(self.report))

    def counts(self, statuses) -> tuple[int, int]:
        return sum(self.written.values()), len(self.failed)


STAGE = Stage("correspond", CorrespondParams, inputs=("characters",), item=_match_block, outputs=("pairs", "status"),
              plan=CorrespondPlan, out_key="dataset", in_key="dataset", refuse_foreign=False,  # adds pairs to its input
              config=correspond_config, what="block", command=("datagen", "correspond"),
              function="mimicbench.datagen.correspond.stage:run_command", step_writes=("pairs",))


def correspond_dataset(dataset_dir, pairs: int | None = None, all_pairs: bool = False, encoder: str = "minilm",
                       temperature: float | None = None, seed: int = 0, clip_model: str = "ViT-B-32",
                       clip_pretrained: str | None = None, progress: bool = True, method: str = DEFAULT_METHOD,
                       no_match: float | None = None, engine: Engine | None = None, block: int = BATCH,
                       unordered: bool = False, across_splits: bool = False) -> dict:
    """Write ``pairs/`` shards (one group per split) and ``correspond_report.json`` (:func:`drive`
    with :data:`STAGE`); return a summary.

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
    params = CorrespondParams(str(dataset_dir), pairs, all_pairs, unordered, across_splits, method=method,
                              no_match=no_match, encoder=encoder, clip_model=clip_model,
                              clip_pretrained=clip_pretrained, temperature=temperature, seed=seed,
                              quiet=not progress, block=block)
    s = drive(STAGE, params, engine=engine)
    return {**s.details, "seconds": s.seconds}


def run_command(params: CorrespondParams) -> StageSummary:
    """``mimicbench datagen correspond``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    check_address_space()
    s = drive(STAGE, params)
    d = s.details
    for failure in d["failed_blocks"] if params.quiet else ():  # else the driver listed them
        print(f"  FAILED {failure}")
    print(f"pairs written: {d['pairs']} with {d['encoder']}, method {d['method']}, in "
          f"{s.seconds:.1f} s (report: {params.dataset}/correspond_report.json)")
    return s

