"""Correspondence at PokeAnimDB size: pairs whose over-relaxed Sinkhorn overflows, one thread,
unordered pairs, the pairs table's encoding, the role report's per-character cache (issue 20)."""
from __future__ import annotations

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch

from mimicbench.datagen.correspond.batched import correspondence_batch, sinkhorn_padded
from mimicbench.datagen.correspond.report import pair_scores
from mimicbench.datagen.correspond.sampling import sample_pairs
from mimicbench.schemas.pair import PairRecord
from mimicbench.schemas.shards import read_records, write_records


def _zoo_skeleton(character_id: str):
    """(canonical names, parents, rest keypoints) of one character of the 975-character zoo, seed 0,
    built alone (its spec from the zoo's plan; no dataset needed)."""
    from mimicbench.datagen.correspond.canonical import canonicalize_names
    from mimicbench.datagen.zoo.build import build_skeleton, naming_style
    from mimicbench.datagen.zoo.naming import bone_names
    from mimicbench.datagen.zoo.plan import plan_zoo
    from mimicbench.schemas.character import HUMANOID_LIKE

    spec = next(s for s in plan_zoo(975, seed=0) if s.character_id == character_id)
    skel, _ = build_skeleton(spec)
    names = bone_names(skel.roles, naming_style(spec), humanoid=spec.category in HUMANOID_LIKE)
    return canonicalize_names(names), skel.parents, skel.heads


def test_a_pair_whose_relaxed_sweeps_overflow_is_redone_with_classic_sweeps():
    """apparel-0006 (81 bones) -> apparel-0047 (240) of the full-size zoo: the over-relaxed sweeps
    (w = 1.7) overflow to NaN; that failed its whole block of 2,048 pairs before. Now the pair is
    solved by classic sweeps and meets the marginals (rows at most 1, columns at most K1/K2 or 1)."""
    from mimicbench.datagen.correspond.encoders import get_encoder
    from mimicbench.datagen.correspond.methods import get_matcher
    from mimicbench.datagen.correspond.structure import skeleton_features
    from mimicbench.datagen.correspond.batched import feature_penalty

    (na, pa, ka), (nb, pb, kb) = _zoo_skeleton("zoo/apparel-0006"), _zoo_skeleton("zoo/apparel-0047")
    enc = get_encoder("minilm")
    ea, eb = enc.embed(na), enc.embed(nb)
    fa, fb = skeleton_features(na, pa, ka).matrix(), skeleton_features(nb, pb, kb).matrix()
    m = get_matcher("structure")
    # the relaxed solver alone does not balance this pair (the condition the fallback exists for)
    cos = torch.from_numpy(ea @ eb.T).clamp(-1, 1)[None]
    scores = m.text * cos - feature_penalty(torch.from_numpy(fa)[None], torch.from_numpy(fb)[None], m.feature_weights())
    relaxed = sinkhorn_padded(scores, torch.tensor([len(na)]), torch.tensor([len(nb)]), m.temperature,
                              dustbin=m.no_match)
    assert not (relaxed.sum(dim=2) <= 1 + 1e-4).all() or not torch.isfinite(relaxed).all()
    (s_cos, hung, sink), = correspondence_batch([ea], [eb], m.temperature, feat_a=[fa], feat_b=[fb],
                                               feature_weights=m.feature_weights(), text_weight=m.text,
                                               no_match=m.no_match)
    assert np.isfinite(sink).all() and (sink >= 0).all()
    assert (sink.sum(axis=1) <= 1 + 1e-4).all()
    assert (sink.sum(axis=0) <= max(1.0, len(na) / len(nb)) + 1e-4).all()
    # the Hungarian pairs are the best matching above the threshold: each a distinct row and column
    assert len(set(hung[:, 0])) == len(set(hung[:, 1])) == len(hung) > 0


def test_the_same_bits_whatever_torchs_thread_count_and_it_is_restored():
    rng = np.random.default_rng(0)
    emb = [(lambda e: (e / np.linalg.norm(e, axis=1, keepdims=True)).astype(np.float32))(rng.normal(size=(k, 32)))
           for k in (40, 180, 200, 120)]
    pairs_a, pairs_b = [emb[0], emb[1], emb[2], emb[3]] * 80, [emb[1], emb[2], emb[3], emb[0]] * 80
    before = torch.get_num_threads()
    try:
        results = []
        for threads in (1, 2):
            torch.set_num_threads(threads)
            results.append(correspondence_batch(pairs_a, pairs_b, 0.1))
            assert torch.get_num_threads() == threads  # the caller's setting is left as it was
    finally:
        torch.set_num_threads(before)
    for x, y in zip(*results):
        for u, v in zip(x, y):
            assert np.array_equal(np.asarray(u).view(np.uint8), np.asarray(v).view(np.uint8))


def test_unordered_pairs_are_each_pair_once_source_id_first():
    chars = [SimpleNamespace(character_id=f"c{i:02d}", category="humanoid" if i % 2 else "bird") for i in range(9)]
    ordered = sample_pairs(chars[::-1], None, True)
    unordered = sample_pairs(chars[::-1], None, True, unordered=True)
    assert len(ordered) == 9 * 8 and len(unordered) == math.comb(9, 2) == 36
    ids = [(a.character_id, b.character_id) for a, b in unordered]
    assert ids == sorted(ids) and all(a < b for a, b in ids)
    assert set(ids) == {(a, b) for a, b in itertools.combinations(sorted(c.character_id for c in chars), 2)}
    assert {frozenset(p) for p in ids} == {frozenset((a.character_id, b.character_id)) for a, b in ordered}
    sampled = sample_pairs(chars, 10, False, seed=3, unordered=True)
    assert len(sampled) == 10 and all(a.character_id < b.character_id for a, b in sampled)
    # PokeAnimDB's count: the unordered pairs among 90% of 975 characters
    assert math.comb(877, 2) == 384_126


def test_pairs_store_m_sink_byte_stream_split_losslessly(tmp_path):
    rng = np.random.default_rng(1)
    rows = []
    for i in range(5):
        k1, k2 = 3 + i, 7 - i
        sink = (rng.random((k1, k2)) * 10.0 ** rng.integers(-30, 0, (k1, k2))).astype(np.float32)
        sink[0, 0] = 0.0
        rows.append(PairRecord(f"a{i}->b{i}", f"a{i}", f"b{i}", "train", k1, k2,
                               rng.random((k1, k2)).astype(np.float32), np.array([[0, 0]], np.int32), sink,
                               "minilm:x", 0.1, "bird", "fish", "structure", {"name": "structure"}))
    write_records(tmp_path, "pairs", rows, split="train")
    path = next((tmp_path / "pairs").glob("*.parquet"))
    meta = pq.ParquetFile(path).metadata.row_group(0)
    enc = {meta.column(i).path_in_schema: meta.column(i).encodings for i in range(meta.num_columns)}
    assert "BYTE_STREAM_SPLIT" in enc["m_sink.list.element"]
    assert "RLE_DICTIONARY" in enc["s_cos.list.element"] and "RLE_DICTIONARY" in enc["pair_id"]
    for want, got in zip(rows, read_records(tmp_path, "pairs")):
        assert got.m_sink.tobytes() == want.m_sink.tobytes() and got.s_cos.tobytes() == want.s_cos.tobytes()


def test_role_report_cache_gives_the_uncached_scores():
    def rec(cid, category, roles):
        return SimpleNamespace(character_id=cid, category=category, bone_roles=roles)

    a = rec("a", "humanoid", ["hips", "spine/1", "left/upper_arm", "right/upper_arm", "head"])
    b = rec("b", "humanoid", ["hips", "spine/1", "right/upper_arm", "left/upper_arm", "neck", "head"])
    c = rec("c", "bird", ["hips", "spine/1", "left/wing/1", "right/wing/1", "head", "left/leg/1"])
    hung = np.array([[0, 0], [1, 1], [2, 3], [3, 2], [4, 5]])
    cache: dict = {}
    for x, y in ((a, b), (b, a), (a, c), (c, a), (a, b)):
        h = hung if (x, y) == (a, b) else np.repeat(np.arange(min(len(x.bone_roles), len(y.bone_roles)))[:, None], 2, 1)
        assert pair_scores(x, y, h, cache) == pair_scores(x, y, h)
    assert set(cache) == {"a", "b", "c"}
    # hand-checked: a->b matches every role exactly (arms swapped back by the Hungarian pairs)
    assert pair_scores(a, b, hung)["exact"] == pytest.approx(1.0)
