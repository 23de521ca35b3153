"""mimicbench.schemas.dataset.Dataset: one manifest read, tables and fingerprints checked against manifest.json
and the shard files read here with plain json, hashlib and pyarrow."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import mimicbench.schemas.manifest as manifest_module
from mimicbench.schemas.dataset import Dataset
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.manifest import mark_incomplete
from mimicbench.schemas.shards import read_records


@pytest.fixture
def manifest_reads(monkeypatch):
    """Counts the parses of manifest.json."""
    count = {"n": 0}
    parse = manifest_module._parse

    def counting(path):
        count["n"] += 1
        return parse(path)

    monkeypatch.setattr(manifest_module, "_parse", counting)
    return count


def test_one_manifest_read_serves_every_question(small_zoo, manifest_reads):
    ds = Dataset.open(small_zoo)
    assert ds.tables == ["characters", "motions", "status"]
    assert ds.has_table("characters", "test") and not ds.has_table("pairs") and ds.entries("pairs") == []
    assert ds.splits("characters") == [s for s in ("train", "val", "test") if ds.has_table("characters", s)]
    chars = ds.records("characters")
    ds.read_table("motions", columns=["motion_id", "fps"])
    ds.fingerprints(["characters", "motions"])
    assert manifest_reads["n"] == 1 and len(chars) == 14


def test_tables_and_fingerprints_match_the_files(small_zoo):
    manifest = json.loads((small_zoo / "manifest.json").read_text())
    ds = Dataset.of(small_zoo)
    for table in ("characters", "motions"):
        shards = manifest["tables"][table]["shards"]
        by_hand = [pq.read_table(small_zoo / s["path"]) for s in shards]
        ids = [i for t in by_hand for i in t.column(f"{table[:-1]}_id").to_pylist()]
        got = ds.read_table(table)
        assert got.num_rows == sum(s["rows"] for s in shards) == len(ids)
        assert got.column(f"{table[:-1]}_id").to_pylist() == ids
        # the fingerprint: sha256 of the canonical JSON of sorted (path, rows, sha256)
        text = json.dumps(sorted([s["path"], s["rows"], s["sha256"]] for s in shards), separators=(",", ":"))
        assert ds.fingerprint(table) == hashlib.sha256(text.encode()).hexdigest()
    test_ids = {r.character_id for r in ds.records("characters", "test")}
    assert test_ids == {r.character_id for r in read_records(small_zoo, "characters") if r.split == "test"}
    with pytest.raises(KeyError, match="no shard of table 'pairs'"):
        ds.fingerprint("pairs")
    with pytest.raises(DatasetError, match="lists no shard of table 'pairs'"):
        ds.records("pairs")


def test_the_handle_is_the_path_it_was_opened_with(small_zoo):
    given = str(small_zoo) + os.sep
    ds = Dataset.open(given)
    assert os.fspath(ds) == str(ds) == given and Path(ds) == small_zoo and Dataset.of(ds) is ds
    assert [r.character_id for r in read_records(ds, "characters")] == [r.character_id for r in ds.records("characters")]


def test_not_a_dataset_and_an_incomplete_one_are_refused(small_zoo, tmp_path):
    with pytest.raises(DatasetError, match="no such dataset folder"):
        Dataset.open(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="manifest.json: missing"):
        Dataset.open(tmp_path / "empty")
    copy = tmp_path / "zoo"
    shutil.copytree(small_zoo, copy)
    mark_incomplete(copy, "zoo")
    with pytest.raises(DatasetError, match="incomplete"):
        Dataset.open(copy)
    ds = Dataset.open(copy, allow_incomplete=True)
    assert len(ds.records("characters")) == 14


def test_bench_run_reads_the_manifest_twice_before_its_first_case(small_zoo, tmp_path, manifest_reads, monkeypatch):
    """Once to check the cases are current, once for the handle (it was 10 separate reads)."""
    import mimicbench.benchmark.evaluator as evaluator
    from tests.bench_fixtures import make_bench_dataset

    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=1, cct_pairs=2, cct_poses=1)
    seen = []
    batch = evaluator.evaluate_batch

    def first(*args, **kwargs):
        seen.append(manifest_reads["n"])
        return batch(*args, **kwargs)

    monkeypatch.setattr(evaluator, "evaluate_batch", first)
    manifest_reads["n"] = 0
    summary = evaluator.run_benchmark(data, ["identity"], out=tmp_path / "res", progress=False, in_process=True)
    assert summary["computed"] > 0 and summary["failed"] == 0
    assert seen[0] == 2
