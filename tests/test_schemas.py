"""Round trips of every record type, the shard writer's atomicity and FORMAT.md."""
import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.columns import records_to_table, table_to_records
from mimicbench.schemas.format_doc import FORMAT_MD, render
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.manifest import load_manifest
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.pair import PairRecord
from mimicbench.schemas.result import ResultRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.tables import RECORD_TYPES
from mimicbench.schemas.version import METADATA_KEY, SCHEMA_VERSION


def make_character(tube, cid="toy/tube-0000", split="train"):
    k, n = len(tube["parents"]), len(tube["vertices"])
    return CharacterRecord(
        character_id=cid, category="unknown", source="tests", split=split,
        vertices=tube["vertices"], faces=tube["faces"], keypoints=tube["keypoints"],
        parents=tube["parents"], bone_names=tube["bone_names"],
        weight_indices=tube["weights"].indices, weight_values=tube["weights"].values,
        apparel_vertex_mask=np.arange(n) % 3 == 0, apparel_bone_mask=np.arange(k) == 1,
        bone_roles=[f"role/{i}" for i in range(k)], skeleton_id="tube", height=1.0,
        meta={"resample": {"faces_in": 10, "ok": True}},
    )


def example_records(tube):
    rng = np.random.default_rng(0)
    k = len(tube["parents"])
    return {
        "characters": [make_character(tube), make_character(tube, "toy/tube-0001")],
        "motions": [MotionRecord("toy/tube-0000/walk", "toy/tube-0000", "walk", "train", 30.0, 4, k,
                                 rng.normal(size=(4, k, 7)).astype(np.float32), "tests")],
        "pairs": [PairRecord("a->b", "a", "b", "train", 3, 2, rng.random((3, 2)).astype(np.float32),
                             np.array([[0, 1], [2, 0]], np.int32), rng.random((3, 2)).astype(np.float32),
                             "minilm:test", 0.1, "humanoid", "bird")],
        "cases": [CaseRecord("h2h/a->b/walk#3", "h2h", "a", "b", "a/walk", 3,
                             rng.normal(size=(k, 7)).astype(np.float32), rng.normal(size=(6, 7)).astype(np.float32),
                             "humanoid", "humanoid"),
                  CaseRecord("cct/a->c/walk#3", "cct", "a", "c", "a/walk", 3,
                             rng.normal(size=(k, 7)).astype(np.float32), None, "humanoid", "bird")],
        "status": [StatusRecord("assets/Fox.glb", "ingest", "failed", "timeout after 5 s", 5.0)],
        "results": [ResultRecord("h2h/a->b/walk#3", "h2h", "identity", "1", "ok", None, 0.01, 3.2, 0.1, 0.98,
                                 None, "humanoid", "humanoid")],
        "rigid_bodies": [RigidBodyRecord("a", 0, "髪", "hair", 1, "capsule", np.float32([0.1, 0.2, 0]),
                                         np.float32([0, 1, 0]), np.float32([1, 0, 0, 0]), 1.0, 0.5, 0.5, 0.0, 0.5,
                                         3, 0xFFF7, "dynamic")],
        "joints": [JointRecord("a", 0, "j", "", "spring_6dof", 0, 1, np.float32([0, 1, 0]), np.float32([1, 0, 0, 0]),
                               *np.float32([[-1, 0, 0], [1, 0, 0], [0, 0, -1], [0, 0, 1], [0, 0, 0], [5, 5, 5]]))],
    }


def assert_record_equal(a, b):
    for name in [c.name for c in type(a).COLUMNS]:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y), err_msg=name)
            assert np.asarray(x).shape == np.asarray(y).shape, name
        elif isinstance(x, float):
            assert np.isclose(x, y), name
        else:
            assert x == y, name


def test_every_record_type_round_trips_in_memory_and_on_disk(tube, tmp_path):
    examples = example_records(tube)
    assert set(examples) == set(RECORD_TYPES)
    for table, records in examples.items():
        arrow = records_to_table(records, RECORD_TYPES[table], table)
        assert arrow.schema.metadata[METADATA_KEY].decode() == SCHEMA_VERSION
        for a, b in zip(records, table_to_records(arrow, RECORD_TYPES[table])):
            assert_record_equal(a, b)
        write_records(tmp_path, table, records, split="train", rows_per_shard=1)
        back = read_records(tmp_path, table)
        assert len(back) == len(records)
        for a, b in zip(records, back):
            assert_record_equal(a, b)
    # plain pandas opens the data
    df = pd.read_parquet(tmp_path / "characters")
    assert list(df["character_id"]) == ["toy/tube-0000", "toy/tube-0001"]


def test_shard_names_manifest_and_rewrite(tube, tmp_path):
    recs = [make_character(tube, f"toy/t-{i}") for i in range(5)]
    write_records(tmp_path, "characters", recs, split="train", rows_per_shard=2, config={"seed": 3})
    names = sorted(p.name for p in (tmp_path / "characters").iterdir())
    assert names == ["train-00000-of-00003.parquet", "train-00001-of-00003.parquet", "train-00002-of-00003.parquet"]
    m = load_manifest(tmp_path)
    assert m["tables"]["characters"]["rows"] == 5 and m["configs"]["characters"] == {"seed": 3}
    assert all(len(s["sha256"]) == 64 for s in m["tables"]["characters"]["shards"])
    # rewriting the split with another shard count removes the stale shards
    write_records(tmp_path, "characters", recs[:1], split="train")
    assert sorted(p.name for p in (tmp_path / "characters").iterdir()) == ["train-00000-of-00001.parquet"]
    write_records(tmp_path, "characters", recs[1:2], split="test")
    assert [r.split for r in read_records(tmp_path, "characters", split="test")] == ["train"]  # stored as given
    assert len(read_records(tmp_path, "characters")) == 2


def test_exception_mid_write_leaves_no_shard_and_manifest_unchanged(tube, tmp_path, monkeypatch):
    write_records(tmp_path, "characters", [make_character(tube)], split="train")
    before = (tmp_path / "manifest.json").read_bytes()
    files_before = sorted(p.name for p in (tmp_path / "characters").iterdir())

    calls = {"n": 0}
    real = pq.write_table

    def failing_write(table, where, **kw):
        calls["n"] += 1
        if calls["n"] == 2:
            with open(where, "wb") as f:  # a partial file under the temporary name
                f.write(b"PAR1 partial")
            raise OSError("disk full (simulated)")
        return real(table, where, **kw)

    monkeypatch.setattr(pq, "write_table", failing_write)
    recs = [make_character(tube, f"toy/t-{i}") for i in range(3)]
    with pytest.raises(OSError, match="disk full"):
        write_records(tmp_path, "characters", recs, split="val", rows_per_shard=1)
    assert (tmp_path / "manifest.json").read_bytes() == before
    # neither the shard completed before the failure nor the partial one exists, under any name
    assert sorted(p.name for p in (tmp_path / "characters").iterdir()) == files_before
    listed = json.loads(before)["tables"]["characters"]["shards"]
    assert [s["path"] for s in listed] == [f"characters/{n}" for n in files_before]


def test_format_md_is_up_to_date_and_documents_every_column():
    text = FORMAT_MD.read_text()
    assert render(text) == text, "schemas/FORMAT.md is stale: run `python -m mimicbench.schemas.format_doc`"
    for rtype in RECORD_TYPES.values():
        for c in rtype.COLUMNS:
            assert f"| `{c.name}` |" in text


def test_dominant_is_the_dense_argmax_ties_to_the_lowest_keypoint():
    from mimicbench.schemas.weights import SparseWeights

    rng = np.random.default_rng(0)
    dense = rng.random((200, 9)) * (rng.random((200, 9)) < 0.4)
    dense[np.arange(200), rng.integers(0, 9, 200)] += 0.01  # every row weighted somewhere
    dense[:20, 2] = dense[:20, 6] = 5.0  # ties between keypoints 2 and 6, stored in either slot order
    w = SparseWeights.from_dense(dense)
    np.testing.assert_array_equal(w.dominant(), np.argmax(w.to_dense(np.float64), axis=1))
    swapped = SparseWeights(w.indices[:, ::-1].copy(), w.values[:, ::-1].copy(), w.num_keypoints)
    np.testing.assert_array_equal(swapped.dominant(), np.argmax(w.to_dense(np.float64), axis=1))
    assert (w.dominant()[:20] == 2).all()
