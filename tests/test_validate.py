"""`mimicbench validate` names each bad file and why."""
import json
import subprocess
import sys

import pytest

from mimicbench.cli import main
from mimicbench.schemas.shards import write_records
from mimicbench.schemas.validate import validate_dataset
from tests.test_schemas import make_character


@pytest.fixture
def dataset(tube, tmp_path):
    root = tmp_path / "ds"
    write_records(root, "characters", [make_character(tube, f"toy/t-{i}") for i in range(4)], "train", rows_per_shard=2)
    write_records(root, "characters", [make_character(tube, "toy/t-9", "test")], "test")
    return root


def shard(root, i=0):
    return root / "characters" / f"train-{i:05d}-of-00002.parquet"


def run_validate(root, capsys):
    code = main(["validate", str(root)])
    return code, capsys.readouterr().out


def test_valid_dataset_passes(dataset, capsys):
    code, out = run_validate(dataset, capsys)
    assert code == 0 and out.startswith("OK") and "characters: 5 rows in 3 shard(s)" in out


def test_truncated_shard(dataset, capsys):
    p = shard(dataset)
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    code, out = run_validate(dataset, capsys)
    assert code == 1 and str(p) in out and "checksum mismatch" in out and "not a readable Parquet" in out


def test_edited_byte(dataset, capsys):
    p = shard(dataset, 1)
    data = bytearray(p.read_bytes())
    data[len(data) // 3] ^= 0xFF
    p.write_bytes(bytes(data))
    code, out = run_validate(dataset, capsys)
    assert code == 1 and f"{p}: checksum mismatch" in out


def test_deleted_shard(dataset, capsys):
    p = shard(dataset)
    p.unlink()
    code, out = run_validate(dataset, capsys)
    assert code == 1 and f"{p}: missing" in out


def test_changed_schema_version(dataset, capsys):
    m = json.loads((dataset / "manifest.json").read_text())
    m["schema_version"] = "9.0"
    (dataset / "manifest.json").write_text(json.dumps(m))
    code, out = run_validate(dataset, capsys)
    assert code == 1 and "manifest.json: unknown schema version '9.0'" in out


def test_shard_written_with_another_schema_version_and_wrong_type(dataset, capsys):
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = shard(dataset)
    t = pq.read_table(p)
    pq.write_table(t.replace_schema_metadata({b"mimicbench.schema_version": b"7.3"}), p)
    t2 = t.set_column(t.column_names.index("parents"), "parents", pa.array([[1.5]] * t.num_rows))
    pq.write_table(t2, shard(dataset, 1))
    problems = validate_dataset(dataset)
    assert any(str(p) in x and "schema version '7.3'" in x for x in problems)
    assert any(str(shard(dataset, 1)) in x and "column 'parents' has type" in x for x in problems)


def test_unlisted_shard_and_missing_manifest(dataset, tmp_path, capsys):
    extra = dataset / "characters" / "val-00000-of-00001.parquet"
    extra.write_bytes(shard(dataset).read_bytes())
    code, out = run_validate(dataset, capsys)
    assert code == 1 and f"{extra}: shard on disk but not listed" in out
    code, out = run_validate(tmp_path / "nothing", capsys)
    assert code == 1 and "not a folder" in out


def test_console_script_help_and_version():
    out = subprocess.run([sys.executable, "-m", "mimicbench", "--help"], capture_output=True, text=True, check=True).stdout
    assert "validate" in out and "mimicbench demo" in out
    ver = subprocess.run([sys.executable, "-m", "mimicbench", "--version"], capture_output=True, text=True, check=True).stdout
    assert ver.strip() == "mimicbench 0.1.0"
