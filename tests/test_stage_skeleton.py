"""The stage skeleton (datagen/stage_runner.py): rows per shard, refusal, reuse, marks, copies.

Each check is against something computed independently: shard counts by hand from the table in
schemas/tables.py, digests with hashlib over the JSON the format spec names, file bytes read back.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from mimicbench.datagen.stage_runner import Stage, StageRun, copy_table, omitted_unless_set
from mimicbench.schemas.errors import DatasetError, UserError
from mimicbench.schemas.manifest import MANIFEST
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.tables import ROWS_PER_SHARD, ROWS_PER_SHARD_OF_STAGE, rows_per_shard


@dataclass(frozen=True)
class ToyParams:
    size: int = 1
    extra: str | None = omitted_unless_set(None)


def _toy(item, size):
    return item * size


TOY = Stage("toy", ToyParams, inputs=("status",), item=_toy, outputs=("status",), made_by="status")


def _rows(n: int, stage: str = "toy") -> list[StatusRecord]:
    return [StatusRecord(f"asset-{i:05d}", stage, "ok", "", 0.0) for i in range(n)]


def _manifest(root: Path) -> dict:
    return json.loads((root / MANIFEST).read_text())


def _input(tmp_path: Path, n: int = 3) -> Path:
    src = tmp_path / "in"
    write_records(src, "status", _rows(n, "zoo"), "zoo")
    return src


def test_rows_per_shard_table_and_stage_exceptions():
    assert rows_per_shard("status") == ROWS_PER_SHARD["status"]
    for (stage, table), n in ROWS_PER_SHARD_OF_STAGE.items():
        assert rows_per_shard(table, stage) == n
    assert rows_per_shard("characters", "zoo") == 1000 and rows_per_shard("characters", "resample") == 500
    assert rows_per_shard("characters", "ingest") == 200 and rows_per_shard("pairs", "correspond") == 5000


def test_status_rows_are_cut_at_the_tables_rows_per_shard(tmp_path):
    n = ROWS_PER_SHARD["status"] + 1
    run = StageRun(TOY, ToyParams(), tmp_path / "out", _input(tmp_path))
    run.begin()
    run.write_status(_rows(n))
    run.finish()
    shards = _manifest(tmp_path / "out")["tables"]["status"]["shards"]
    assert len(shards) == math.ceil(n / ROWS_PER_SHARD["status"]) == 2
    assert [pq.read_metadata(tmp_path / "out" / s["path"]).num_rows for s in shards] == [ROWS_PER_SHARD["status"], 1]
    assert _manifest(tmp_path / "out")["complete"] is True and "pending" not in _manifest(tmp_path / "out")


def test_config_is_the_params_and_input_fingerprints_as_the_format_says(tmp_path):
    src = _input(tmp_path)
    run = StageRun(TOY, ToyParams(size=3), tmp_path / "out", src, info={"source": "x"})
    params = {"stage": "toy", "size": 3}  # ``extra`` at its default is left out
    want = hashlib.sha256(json.dumps(params, sort_keys=True, separators=(",", ":")).encode()).hexdigest()
    fp = run.config["fingerprint"]
    assert fp["config"] == want and fp["params"] == ["size", "stage"] and run.config["source"] == "x"
    shards = _manifest(src)["tables"]["status"]["shards"]
    table = json.dumps(sorted([s["path"], s["rows"], s["sha256"]] for s in shards), sort_keys=True,
                       separators=(",", ":"))
    assert fp["inputs"] == {"status": hashlib.sha256(table.encode()).hexdigest()}
    assert fp["inputs_from"] == str(src.resolve())
    assert StageRun(TOY, ToyParams(extra="y"), tmp_path / "out", src).config["extra"] == "y"


def test_folders_inside_one_another_are_refused(tmp_path):
    src = _input(tmp_path)
    for out in (src, src / "inner", tmp_path):
        with pytest.raises(UserError, match="must be separate folders"):
            StageRun(TOY, ToyParams(), out, src)
    assert StageRun(TOY, ToyParams(), src, src, refuse_foreign=False).config["fingerprint"]["inputs_from"] == "."


def test_a_dataset_made_by_another_stage_is_refused_and_left_as_it_was(tmp_path):
    out = tmp_path / "out"
    write_records(out, "status", _rows(2, "zoo"), "zoo", config={"stage": "zoo"})
    before = (out / MANIFEST).read_bytes()
    with pytest.raises(DatasetError, match="holds a dataset made by zoo, not by toy"):
        StageRun(TOY, ToyParams(), out, _input(tmp_path))
    assert (out / MANIFEST).read_bytes() == before


def test_earlier_rows_are_reusable_only_under_the_same_fingerprints(tmp_path):
    src, out = _input(tmp_path), tmp_path / "out"
    first = StageRun(TOY, ToyParams(size=2), out, src)
    assert first.previous()[0] is None  # nothing there yet
    first.begin()
    first.write_status(_rows(2))
    first.finish()
    assert StageRun(TOY, ToyParams(size=2), out, src).previous()[1] is None
    assert "parameters changed (size 2 -> 5)" in StageRun(TOY, ToyParams(size=5), out, src).previous()[1]
    write_records(src, "status", _rows(4, "zoo"), "zoo")  # the input table changes
    assert "input table(s) status changed" in StageRun(TOY, ToyParams(size=2), out, src).previous()[1]


def test_a_pending_run_is_reused_by_its_own_config(tmp_path):
    src, out = _input(tmp_path), tmp_path / "out"
    killed = StageRun(TOY, ToyParams(size=7), out, src)
    killed.begin()
    killed.write("status", _rows(1), "part_00000", config=None)  # a part, the run then killed
    assert _manifest(out)["complete"] is False and _manifest(out)["pending"]["stage"] == "toy"
    assert StageRun(TOY, ToyParams(size=7), out, src).previous()[1] is None
    assert StageRun(TOY, ToyParams(size=7), out, src).previous(pending=False)[1] is not None  # no final config


def test_abandon_restores_the_manifest_or_removes_the_new_folder(tmp_path):
    src = _input(tmp_path)
    fresh = StageRun(TOY, ToyParams(), tmp_path / "new", src)
    fresh.begin()
    err = fresh.abandon([StatusRecord("a", "toy", "failed", "boom", 0.0)], "asset")
    assert "every asset failed (a: boom)" in str(err) and "nothing written" in str(err)
    assert not (tmp_path / "new").exists()
    out = tmp_path / "out"
    done = StageRun(TOY, ToyParams(), out, src)
    done.begin()
    done.write_status(_rows(1))
    done.finish()
    before = _manifest(out)
    again = StageRun(TOY, ToyParams(), out, src)
    again.begin()
    again.abandon([], "asset")
    assert _manifest(out) == before


def test_streams_abort_on_an_exception_and_close_otherwise(tmp_path):
    src, out = _input(tmp_path), tmp_path / "out"
    run = StageRun(TOY, ToyParams(), out, src)
    run.begin()
    with pytest.raises(RuntimeError):
        with run.streams([("status", "a")]) as streams:
            streams["status", "a"].add(_rows(3))
            raise RuntimeError("killed")
    assert "status" not in _manifest(out)["tables"]
    assert not list((out / "status").glob("*.parquet"))
    with run.streams([("status", "a")]) as streams:
        streams["status", "a"].add(_rows(3))
    assert [r.asset for r in read_records(out, "status", "a", allow_incomplete=True)] == [r.asset for r in _rows(3)]


def test_copy_table_copies_verified_bytes_and_renames_a_local_input(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    write_records(src, "status", _rows(5, "zoo"), "zoo",
                  config={"stage": "x", "fingerprint": {"inputs": {}, "inputs_from": "."}})
    write_records(dst, "status", _rows(1, "old"), "old")
    copy_table(src, dst, "status")
    s_entries, d_entries = _manifest(src)["tables"]["status"], _manifest(dst)["tables"]["status"]
    assert d_entries == s_entries
    for e in d_entries["shards"]:
        assert (dst / e["path"]).read_bytes() == (src / e["path"]).read_bytes()
        assert hashlib.sha256((dst / e["path"]).read_bytes()).hexdigest() == e["sha256"]
    assert not (dst / "status" / "old-00000-of-00001.parquet").exists()  # the replaced shard is gone
    assert _manifest(dst)["configs"]["status"]["fingerprint"]["inputs_from"] == str(src.resolve())
    (src / d_entries["shards"][0]["path"]).write_bytes(b"damaged")
    with pytest.raises(DatasetError):
        copy_table(src, dst, "status")
    assert (dst / d_entries["shards"][0]["path"]).read_bytes() != b"damaged"
