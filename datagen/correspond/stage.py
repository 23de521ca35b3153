"""The correspond stage: ``pairs/`` shards for a dataset, and one pair on the fly."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from datagen.correspond.canonical import canonicalize_names
from datagen.correspond.encoders import get_encoder
from datagen.correspond.report import format_report, role_agreement_report
from datagen.correspond.sampling import INTRA_FRACTION, sample_pairs
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
    """One pair on the fly from two bone-name lists (e.g. a pair that was not precomputed).

    Returns S_cos (K1, K2) float32, Hungarian pairs (min(K1, K2), 2) int32 and M_sink (K1, K2)
    float32, as stored in ``pairs/``. The encoder and each canonical name's embedding are cached,
    so repeated calls cost only the matrices.
    """
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    ca, cb = canonicalize_names(list(names_a)), canonicalize_names(list(names_b))
    if not ca or not cb:
        raise ValueError(f"names_a, names_b: expected non-empty name lists, got {len(ca)} and {len(cb)} names")
    table = _embed_cached(enc, ca + cb)
    return correspondence_batch([np.stack([table[t] for t in ca])], [np.stack([table[t] for t in cb])], temperature)[0]


def correspond_dataset(dataset_dir, pairs: int | None = None, all_pairs: bool = False, encoder: str = "minilm",
                       temperature: float = DEFAULT_TEMPERATURE, seed: int = 0, clip_model: str = "ViT-B-32",
                       clip_pretrained: str | None = None, progress: bool = True) -> dict:
    """Write ``pairs/`` shards (one group per split) and ``correspond_report.json``; return a summary.

    Args:
        dataset_dir: dataset folder with a ``characters`` table.
        pairs: ordered pairs per split to sample (ignored with ``all_pairs``); None means all.
        all_pairs: every ordered pair within each split.
        encoder: ``minilm`` (offline default) or ``clip``.
        temperature: Sinkhorn temperature T on cosine similarities (default 0.1: a cosine gap of
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
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    emb = embed_skeletons(records, enc)
    written, all_pairs_out = {}, []
    config = stage_config({"stage": "correspond", "encoder": enc.name, "temperature": temperature, "seed": seed,
                           "pairs": pairs, "all_pairs": all_pairs, "intra_fraction": INTRA_FRACTION},
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
            mats = correspondence_batch([emb[a.character_id] for a, _ in batch], [emb[b.character_id] for _, b in batch],
                                        temperature)
            for (a, b), (s, h, m) in zip(batch, mats):
                out.append(PairRecord(f"{a.character_id}->{b.character_id}", a.character_id, b.character_id, split,
                                      a.num_joints, b.num_joints, s, h, m, enc.name, float(temperature),
                                      a.category, b.category))
            bar.update(len(batch))
        bar.close()
        out = [rec for _, rec in sorted(zip(order, out), key=lambda x: x[0])]
        write_records(dataset_dir, "pairs", out, split=split, rows_per_shard=20000, config=config)
        written[split] = len(out)
        all_pairs_out.extend(out)
    report = role_agreement_report(by_id, all_pairs_out)
    atomic_write_bytes(dataset_dir / "correspond_report.json", (json.dumps(report, indent=2) + "\n").encode())
    if progress:
        print(format_report(report))
    return {"pairs": written, "encoder": enc.name, "temperature": temperature, "report": report,
            "seconds": time.perf_counter() - start}
