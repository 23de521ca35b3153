"""The correspond stage: ``pairs/`` shards for a dataset, and one pair on the fly.

The method is chosen by name (:mod:`.methods`): ``structure`` (default) or ``text`` (the paper's).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from datagen.correspond.canonical import canonicalize_names
from datagen.correspond.encoders import get_encoder
from datagen.correspond.methods import DEFAULT_METHOD, get_method, match_batch, skeleton_feature_table
from datagen.correspond.report import format_report, role_agreement_report
from datagen.correspond.sampling import INTRA_FRACTION, sample_pairs
from datagen.correspond.structure import skeleton_features
from schemas.errors import DatasetError
from schemas.fingerprint import stage_config, tables_fingerprint
from schemas.manifest import atomic_write_bytes
from schemas.pair import PairRecord
from schemas.shards import read_records, splits_of, write_records

BATCH = 2048


def embed_skeletons(records, encoder) -> dict[str, np.ndarray]:
    """Per character ID its (K, d) unit embeddings; each unique canonical name is embedded once."""
    canon = {r.character_id: canonicalize_names(r.bone_names) for r in records}
    unique = sorted({t for names in canon.values() for t in names})
    table = dict(zip(unique, encoder.embed(unique))) if unique else {}
    return {cid: np.stack([table[t] for t in names]) for cid, names in canon.items() if names}


def _embed_cached(enc, texts: list[str]) -> dict[str, np.ndarray]:
    """Embeddings of ``texts`` by ``enc``, remembering every text the encoder has seen."""
    cache = _EMBEDDING_CACHE.setdefault(enc.name, {})
    missing = sorted(set(texts) - cache.keys())
    if missing:
        cache.update(zip(missing, enc.embed(missing)))
    return cache


_EMBEDDING_CACHE: dict[str, dict[str, np.ndarray]] = {}


def correspondence_for_names(names_a, names_b, encoder: str = "minilm", temperature: float = DEFAULT_TEMPERATURE,
                             clip_model: str = "ViT-B-32", clip_pretrained: str | None = None):
    """One pair on the fly from two bone-name lists, by the text-only method (names are all it has).

    Returns S_cos (K1, K2) float32, Hungarian pairs (min(K1, K2), 2) int32 and M_sink (K1, K2)
    float32, as stored in ``pairs/`` by ``--method text``. The encoder and each canonical name's
    embedding are cached, so repeated calls cost only the matrices. With the skeletons at hand,
    :func:`correspondence_for_skeletons` gives the structure-aware default.
    """
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    ca, cb = canonicalize_names(list(names_a)), canonicalize_names(list(names_b))
    if not ca or not cb:
        raise ValueError(f"names_a, names_b: expected non-empty name lists, got {len(ca)} and {len(cb)} names")
    table = _embed_cached(enc, ca + cb)
    return correspondence_batch([np.stack([table[t] for t in ca])], [np.stack([table[t] for t in cb])], temperature)[0]


def correspondence_for_skeletons(names_a, parents_a, keypoints_a, names_b, parents_b, keypoints_b,
                                 method: str = DEFAULT_METHOD, encoder: str = "minilm",
                                 temperature: float | None = None, no_match: float | None = None,
                                 clip_model: str = "ViT-B-32", clip_pretrained: str | None = None):
    """One pair on the fly from two skeletons: names (K,), parents (K,) and rest keypoints (K, 3).

    Returns S_cos (K1, K2), Hungarian pairs (P, 2) int32 and M_sink (K1, K2) as ``pairs/`` stores
    them for ``method`` (``structure`` by default, or ``text``).
    """
    m = get_method(method, temperature, no_match)
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    ca, cb = canonicalize_names(list(names_a)), canonicalize_names(list(names_b))
    if not ca or not cb:
        raise ValueError(f"names_a, names_b: expected non-empty name lists, got {len(ca)} and {len(cb)} names")
    table = _embed_cached(enc, ca + cb)
    ea, eb = [np.stack([table[t] for t in ca])], [np.stack([table[t] for t in cb])]
    if not m.uses_structure:
        return match_batch(m, ea, eb)[0]
    fa = skeleton_features(ca, parents_a, keypoints_a).matrix()
    fb = skeleton_features(cb, parents_b, keypoints_b).matrix()
    return match_batch(m, ea, eb, [fa], [fb])[0]


def correspond_dataset(dataset_dir, pairs: int | None = None, all_pairs: bool = False, encoder: str = "minilm",
                       temperature: float | None = None, seed: int = 0, clip_model: str = "ViT-B-32",
                       clip_pretrained: str | None = None, progress: bool = True, method: str = DEFAULT_METHOD,
                       no_match: float | None = None) -> dict:
    """Write ``pairs/`` shards (one group per split) and ``correspond_report.json``; return a summary.

    Args:
        dataset_dir: dataset folder with a ``characters`` table.
        pairs: ordered pairs per split to sample (ignored with ``all_pairs``); None means all.
        all_pairs: every ordered pair within each split.
        encoder: ``minilm`` (offline default) or ``clip``.
        method: ``structure`` (default: text and skeleton, no-match threshold) or ``text`` (the
            paper's S_cos, Hungarian, Sinkhorn); see :mod:`datagen.correspond.methods`.
        no_match: the structure method's no-match threshold (default 0.45).
        temperature: Sinkhorn temperature T on the scores (default 0.1: a score gap of
            0.1 between two candidate names weighs e times more, so M_sink spreads over names
            that are nearly as similar, such as neighbouring chain segments, while the one-to-one
            answer is stored separately as M_hung. On 300 zoo pairs Sinkhorn needed a median of 21
            sweeps and at most 261; at 0.05 a few pairs needed thousands).
        seed: pair sampling seed.
    """
    start = time.perf_counter()
    dataset_dir = Path(dataset_dir)
    records = [r for r in read_records(dataset_dir, "characters") if r.num_joints > 0]  # DatasetError if no dataset
    if not records:
        raise DatasetError(f"{dataset_dir}: no character with bones in the characters table; nothing to correspond")
    by_id = {r.character_id: r for r in records}
    m = get_method(method, temperature, no_match)
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    emb = embed_skeletons(records, enc)
    feats = skeleton_feature_table(records) if m.uses_structure else {}
    params = json.loads(m.params_json())
    written, all_pairs_out = {}, []
    config = stage_config({"stage": "correspond", "encoder": enc.name, "temperature": m.temperature, "seed": seed,
                           "pairs": pairs, "all_pairs": all_pairs, "intra_fraction": INTRA_FRACTION, "method": params},
                          tables_fingerprint(dataset_dir, ["characters"]))
    for split in splits_of(dataset_dir, "characters"):
        chosen = sample_pairs([r for r in records if r.split == split], pairs, all_pairs, seed)
        # batch pairs of similar sizes together (less padding); rows are written in sampled order
        order = sorted(range(len(chosen)), key=lambda i: (chosen[i][0].num_joints, chosen[i][1].num_joints))
        chosen = [chosen[i] for i in order]
        out = []
        bar = tqdm(total=len(chosen), desc=f"correspond/{split}", unit="pair", disable=not progress)
        for i in range(0, len(chosen), BATCH):
            batch = chosen[i:i + BATCH]
            mats = match_batch(m, [emb[a.character_id] for a, _ in batch], [emb[b.character_id] for _, b in batch],
                               [feats[a.character_id] for a, _ in batch] if feats else None,
                               [feats[b.character_id] for _, b in batch] if feats else None)
            for (a, b), (s, h, sink) in zip(batch, mats):
                out.append(PairRecord(f"{a.character_id}->{b.character_id}", a.character_id, b.character_id, split,
                                      a.num_joints, b.num_joints, s, h, sink, enc.name, float(m.temperature),
                                      a.category, b.category, m.name, params))
            bar.update(len(batch))
        bar.close()
        out = [rec for _, rec in sorted(zip(order, out), key=lambda x: x[0])]
        write_records(dataset_dir, "pairs", out, split=split, rows_per_shard=20000, config=config)
        written[split] = len(out)
        all_pairs_out.extend(out)
    report = role_agreement_report(by_id, all_pairs_out, params)
    atomic_write_bytes(dataset_dir / "correspond_report.json", (json.dumps(report, indent=2) + "\n").encode())
    if progress:
        print(format_report(report))
    return {"pairs": written, "encoder": enc.name, "method": m.name, "temperature": m.temperature, "report": report,
            "seconds": time.perf_counter() - start}
