"""Data integrity (issue 12): each test shows a wrong result or a loss that no longer happens.

Checksums are compared with ``hashlib`` directly, file modes with the umask arithmetic of POSIX
``open(O_CREAT, 0666)``, and folder contents byte for byte before and after.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from mimicbench.datagen.resample.stage import resample_dataset
from mimicbench.cli import main
from mimicbench.schemas import integrity
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.fingerprint import stage_config, tables_fingerprint
from mimicbench.schemas.manifest import load_manifest, load_manifest_for_write
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.validate import validate_dataset
from tests.test_resample import bend_motion
from tests.test_schemas import make_character

REPO = Path(__file__).resolve().parents[1]


def toy_dataset(root: Path, tube, n: int = 3) -> Path:
    chars = [make_character(tube, f"toy/t-{i}") for i in range(n)]
    write_records(root, "characters", chars, "train")
    write_records(root, "motions", [bend_motion(c) for c in chars], "train")
    return root


def snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def manifest_of(root: Path) -> dict:
    return json.loads((root / "manifest.json").read_text())


def cli(argv, capsys) -> tuple[int, str]:
    code = main(argv)
    return code, capsys.readouterr().err


# -- item 2: every read verifies size and sha256 ------------------------------------------------

def test_a_flipped_byte_in_a_motions_shard_fails_the_read_naming_the_file(tube, tmp_path, capsys):
    root = toy_dataset(tmp_path / "ds", tube)
    shard = root / manifest_of(root)["tables"]["motions"]["shards"][0]["path"]
    entry = manifest_of(root)["tables"]["motions"]["shards"][0]
    assert entry["sha256"] == hashlib.sha256(shard.read_bytes()).hexdigest() and entry["bytes"] == shard.stat().st_size
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0x01  # same size, one bit
    shard.write_bytes(bytes(data))
    integrity.forget_digests()
    with pytest.raises(DatasetError, match=f"{shard}: sha256 .* differs from manifest.json"):
        read_records(root, "motions")
    assert len(read_records(root, "characters")) == 3  # the other table is intact
    # the stages stop before using it: exit 2, the file named, no output folder made
    code, err = cli(["datagen", "resample", str(root), str(tmp_path / "out"), "--quiet"], capsys)
    assert code == 2 and err.startswith("mimicbench: error: ") and str(shard) in err
    assert not (tmp_path / "out").exists()


def test_a_truncated_shard_is_caught_by_its_size_even_without_hashing(tube, tmp_path, monkeypatch):
    root = toy_dataset(tmp_path / "ds", tube)
    shard = root / manifest_of(root)["tables"]["characters"]["shards"][0]["path"]
    shard.write_bytes(shard.read_bytes()[:-10])
    monkeypatch.setenv("MIMICBENCH_VERIFY", "0")
    with pytest.raises(DatasetError, match=f"{shard}: .* bytes, manifest.json says"):
        read_records(root, "characters")


def test_each_file_is_hashed_once_per_process_and_the_opt_out_skips_it(tube, tmp_path, monkeypatch):
    root = toy_dataset(tmp_path / "ds", tube)
    integrity.forget_digests()
    hashed = []
    real = integrity.sha256_of
    monkeypatch.setattr(integrity, "sha256_of", lambda p: hashed.append(Path(p).name) or real(p))
    for _ in range(2):  # just written: its times may not have ticked yet, so each read hashes it
        read_records(root, "characters")
    assert hashed == ["train-00000-of-00001.parquet"] * 2
    monkeypatch.setattr(integrity, "RACY_SECONDS", -1.0)  # as if written long ago
    for _ in range(3):
        read_records(root, "characters")
    assert len(hashed) == 3
    integrity.forget_digests()
    read_records(root, "characters", verify=False)
    monkeypatch.setenv("MIMICBENCH_VERIFY", "0")
    read_records(root, "characters")
    assert len(hashed) == 3


# -- item 3: resume only when the fingerprints of inputs and parameters match -------------------

def test_resampling_with_other_faces_into_an_earlier_run_redoes_every_character(tube, tmp_path, capsys):
    src = toy_dataset(tmp_path / "in", tube)
    out = tmp_path / "out"
    first = resample_dataset(src, out, faces=200, progress=False)
    assert first["resampled"] == 3
    again = resample_dataset(src, out, faces=200, progress=False)
    assert again["resampled"] == 0 and again["already_done"] == 3
    assert main(["datagen", "resample", str(src), str(out), "--faces", "400"]) == 0
    printed = capsys.readouterr().out
    assert "faces 200 -> 400" in printed and "3 resampled, 0 already done" in printed
    chars = read_records(out, "characters")
    assert {c.meta["resample"]["faces_out"] for c in chars} == {400}
    assert all(abs(len(c.faces) - 400) <= 4 for c in chars)
    config = load_manifest(out)["configs"]["characters"]
    assert config["faces"] == 400 and config["fingerprint"]["inputs"] == tables_fingerprint(src, ["characters", "motions"])
    # a changed input table is redone too, even with the same parameters
    write_records(src, "characters", [make_character(tube, f"toy/t-{i}") for i in range(2)], "train")
    write_records(src, "motions", [bend_motion(make_character(tube, f"toy/t-{i}")) for i in range(2)], "train")
    third = resample_dataset(src, out, faces=400, progress=False)
    assert third["already_done"] == 0 and third["resampled"] == 2
    assert sorted(c.character_id for c in read_records(out, "characters")) == ["toy/t-0", "toy/t-1"]
    assert validate_dataset(out) == []


def test_a_table_derived_from_tables_that_changed_since_is_refused_and_flagged(tube, tmp_path):
    root = toy_dataset(tmp_path / "ds", tube)
    config = stage_config({"stage": "unit"}, tables_fingerprint(root, ["characters"]))
    write_records(root, "status", [], split="unit", config=config)
    assert validate_dataset(root) == []
    write_records(root, "characters", [make_character(tube, "toy/other")], "train")  # a regenerated input
    assert any("table 'status' was made from other characters" in p for p in validate_dataset(root))
    with pytest.raises(DatasetError, match="table 'status' was made from other characters.*re-run unit"):
        read_records(root, "status")


# -- item 4: a missing manifest or an empty input is an error ------------------------------------

def test_a_missing_manifest_is_an_error_for_readers_and_stages(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DatasetError, match="manifest.json: missing"):
        read_records(empty, "characters")
    assert load_manifest_for_write(tmp_path / "new")["tables"] == {}  # writers may start a dataset
    for folder in (tmp_path / "nowhere", empty):
        code, err = cli(["datagen", "resample", str(folder), str(tmp_path / "out"), "--quiet"], capsys)
        assert code == 2 and err.startswith(f"mimicbench: error: {folder}")
        code, err = cli(["datagen", "correspond", str(folder), "--quiet"], capsys)
        assert code == 2 and err.startswith(f"mimicbench: error: {folder}")
    assert not (tmp_path / "nowhere").exists() and not (tmp_path / "out").exists()
    assert list(empty.iterdir()) == []


def test_an_empty_or_absent_input_table_is_an_error(tube, tmp_path, capsys):
    root = tmp_path / "ds"
    write_records(root, "characters", [], "train")
    write_records(root, "motions", [], "train")
    code, err = cli(["datagen", "resample", str(root), str(tmp_path / "out"), "--quiet"], capsys)
    assert code == 2 and "characters table has no rows" in err and not (tmp_path / "out").exists()
    code, err = cli(["datagen", "correspond", str(root), "--quiet"], capsys)
    assert code == 2 and "no character with bones" in err and "pairs" not in manifest_of(root)["tables"]
    with pytest.raises(DatasetError, match="lists no shard of table 'pairs'"):
        read_records(root, "pairs")


# -- item 5: a stage that produced nothing never replaces existing data ---------------------------

def test_a_zoo_where_every_character_fails_leaves_the_existing_zoo_untouched(tmp_path, capsys, monkeypatch):
    import mimicbench.datagen.zoo.dataset as zoo_dataset

    out = tmp_path / "zoo"
    assert main(["zoo", "--out", str(out), "--characters", "2", "--quiet", "--no-contact-sheet"]) == 0
    capsys.readouterr()
    before = snapshot(out)
    with pytest.raises(SystemExit) as exc:  # the CLI refuses a negative seed up front
        main(["zoo", "--out", str(out), "--characters", "2", "--seed", "-1", "--quiet"])
    assert exc.value.code == 2 and "--seed: expected an integer >= 0" in capsys.readouterr().err

    def broken(spec, split, clips, *rest):
        raise RuntimeError(f"cannot build {spec.character_id}")

    monkeypatch.setattr(zoo_dataset, "build_character", broken)
    code, err = cli(["zoo", "--out", str(out), "--characters", "3", "--seed", "4", "--quiet", "--no-contact-sheet"],
                    capsys)
    assert code == 2 and "every one of the 3 characters failed" in err and "cannot build zoo/" in err
    assert snapshot(out) == before and validate_dataset(out) == []


def test_zoo_and_resample_refuse_to_overwrite_a_dataset_another_stage_made(tube, tmp_path, capsys):
    src = toy_dataset(tmp_path / "in", tube)
    before = snapshot(src)
    code, err = cli(["zoo", "--out", str(src), "--characters", "2", "--quiet", "--no-contact-sheet"], capsys)
    assert code == 2 and "not by the zoo" in err
    other = toy_dataset(tmp_path / "other", tube)
    code, err = cli(["datagen", "resample", str(other), str(src), "--quiet"], capsys)
    assert code == 2 and "not by resample" in err
    assert snapshot(src) == before


# -- item 7: manifest paths are confined to the dataset folder ---------------------------------

@pytest.mark.parametrize("how", ["dotdot", "absolute", "symlink"])
def test_manifest_paths_outside_the_dataset_are_refused(tube, tmp_path, capsys, how):
    src = toy_dataset(tmp_path / "a" / "b" / "in", tube)
    outside = tmp_path / "x"
    outside.mkdir()
    m = manifest_of(src)
    entry = m["tables"]["motions"]["shards"][0]
    shutil.copy(src / entry["path"], outside / "evil.parquet")
    if how == "dotdot":
        entry["path"] = "../../x/evil.parquet"
    elif how == "absolute":
        entry["path"] = str(outside / "evil.parquet")
    else:
        shutil.rmtree(src / "motions")
        (outside / entry["path"].split("/")[1]).write_bytes((outside / "evil.parquet").read_bytes())
        (src / "motions").symlink_to(outside, target_is_directory=True)
    (src / "manifest.json").write_text(json.dumps(m))
    problems = validate_dataset(src)
    assert any("leaves the dataset folder" in p or "leads outside the dataset folder" in p for p in problems)
    with pytest.raises(DatasetError, match="outside the dataset folder|leaves the dataset folder"):
        read_records(src, "motions")
    out = tmp_path / "a" / "b" / "out"
    before = snapshot(tmp_path / "x")
    code, err = cli(["datagen", "resample", str(src), str(out), "--faces", "200", "--quiet"], capsys)
    assert code == 2 and "mimicbench: error:" in err
    assert snapshot(tmp_path / "x") == before
    assert not (tmp_path / "a" / "x").exists()  # out/../../x/evil.parquet was not written
    if how == "symlink":  # a writer does not follow a table folder that leads out either
        with pytest.raises(DatasetError, match="outside the dataset folder"):
            write_records(src, "motions", [], "val")
        assert snapshot(tmp_path / "x") == before


# -- item 9: resample writes as it goes; a killed run resumes; validate sees a half output -------

KILLABLE = """
import sys, time
import mimicbench.datagen.resample.stage as stage
real, calls = stage.resample_character, []
def slow(*args):
    calls.append(1)
    if len(calls) > 2:
        time.sleep(600)  # killed here, with two characters finished
    return real(*args)
stage.resample_character = slow
stage.resample_dataset(sys.argv[1], sys.argv[2], faces=200, progress=False, flush_every=1)
"""


def test_a_resample_killed_mid_run_keeps_its_work_and_a_rerun_resumes_it(tube, tmp_path):
    src = toy_dataset(tmp_path / "in", tube, n=5)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(KILLABLE), str(src), str(out)], env=env)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            m = json.loads((out / "manifest.json").read_text()) if (out / "manifest.json").exists() else {}
            if m.get("tables", {}).get("characters", {}).get("rows", 0) >= 2:
                break
            time.sleep(0.2)
        assert proc.poll() is None, "the resample child ended before it could be killed"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    m = manifest_of(out)
    assert m["complete"] is False and m["pending"]["stage"] == "resample"
    assert {s["split"] for s in m["tables"]["characters"]["shards"]} == {"part_00000", "part_00001"}
    assert any("incomplete (resample started writing it" in p for p in validate_dataset(out))
    with pytest.raises(DatasetError, match="incomplete"):
        read_records(out, "characters")
    summary = resample_dataset(src, out, faces=200, progress=False)
    assert summary["already_done"] == 2 and summary["resampled"] == 3
    assert validate_dataset(out) == []
    assert sorted(c.character_id for c in read_records(out, "characters")) == [f"toy/t-{i}" for i in range(5)]
    assert {s["split"] for s in manifest_of(out)["tables"]["characters"]["shards"]} == {"train"}


# -- item 10: schema versions, umask, CLI errors ------------------------------------------------

def test_an_unknown_schema_major_is_refused_by_readers_and_not_overwritten_by_writers(tube, tmp_path):
    root = toy_dataset(tmp_path / "ds", tube)
    m = manifest_of(root)
    m["schema_version"] = "2.0"
    (root / "manifest.json").write_text(json.dumps(m))
    before = snapshot(root)
    with pytest.raises(DatasetError, match="unknown schema version '2.0'"):
        read_records(root, "characters")
    with pytest.raises(DatasetError, match="unknown schema version '2.0'"):
        write_records(root, "characters", [make_character(tube, "toy/x")], "val")
    assert snapshot(root) == before
    m["schema_version"] = "1.7"  # a newer minor: readable, and a write does not downgrade it
    (root / "manifest.json").write_text(json.dumps(m))
    assert len(read_records(root, "characters")) == 3
    write_records(root, "characters", [make_character(tube, "toy/x")], "val")
    assert manifest_of(root)["schema_version"] == "1.7"


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o027])
def test_shards_manifests_and_copies_get_the_users_umask(tube, tmp_path, mask):
    old = os.umask(mask)
    try:
        src = toy_dataset(tmp_path / "in", tube, n=1)
        resample_dataset(src, tmp_path / "out", faces=200, progress=False)
    finally:
        os.umask(old)
    files = [p for d in (src, tmp_path / "out") for p in d.rglob("*") if p.is_file()]
    assert len(files) >= 6
    for p in files:
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask, p


@pytest.mark.parametrize("manifest,said", [
    ([], "expected a JSON object, got list"),
    ({"schema_version": "1.0", "tables": []}, "'tables' must be an object"),
    ({"schema_version": "1.0", "tables": {"characters": {"shards": [{"path": 3}]}}}, "'path' must be a string, got 3"),
    ({"schema_version": "1.0", "tables": {"characters": {"shards": [
        {"path": "characters/train-00000-of-00001.parquet", "split": "train", "rows": -1, "sha256": "x"}]}}},
     "'rows' must be a non-negative integer, got -1"),
    ({"schema_version": "1.0", "complete": "no"}, "'complete' must be true or false"),
    ({"schema_version": 1}, "unknown schema version 1"),
])
def test_a_malformed_manifest_is_a_named_error_for_readers_and_validate(tmp_path, manifest, said, capsys):
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match=said):
        read_records(tmp_path, "characters")
    assert [said in p for p in validate_dataset(tmp_path)] == [True]
    code, err = cli(["datagen", "correspond", str(tmp_path), "--quiet"], capsys)
    assert code == 2 and said in err


def test_a_resample_where_every_character_fails_leaves_the_earlier_output_untouched(tube, tmp_path, capsys,
                                                                                     monkeypatch):
    import mimicbench.datagen.resample.stage as stage

    src = toy_dataset(tmp_path / "in", tube)
    out = tmp_path / "out"
    resample_dataset(src, out, faces=200, progress=False)
    before = snapshot(out)

    def broken(record, motions, faces, backend):
        raise RuntimeError(f"cannot resample {record.character_id}")

    monkeypatch.setattr(stage, "resample_character", broken)
    code, err = cli(["datagen", "resample", str(src), str(out), "--faces", "400", "--quiet"], capsys)
    assert code == 2 and "every character failed" in err and "cannot resample toy/t-0" in err
    assert snapshot(out) == before and validate_dataset(out) == []
    code, err = cli(["datagen", "resample", str(src), str(tmp_path / "new"), "--faces", "400", "--quiet"], capsys)
    assert code == 2 and "nothing written" in err and not (tmp_path / "new").exists()


def test_resume_redoes_a_split_whose_shard_no_longer_matches_the_manifest(tube, tmp_path):
    """A kill between renaming a final shard and rewriting the manifest leaves a listed shard with
    another checksum: the resume redoes those rows instead of failing or trusting them."""
    src = toy_dataset(tmp_path / "in", tube)
    out = tmp_path / "out"
    resample_dataset(src, out, faces=200, progress=False)
    shard = out / manifest_of(out)["tables"]["characters"]["shards"][0]["path"]
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0x01
    shard.write_bytes(bytes(data))
    summary = resample_dataset(src, out, faces=200, progress=False)
    assert summary["resampled"] == 3 and "cannot be reused and are redone" in summary["notes"][0]
    assert validate_dataset(out) == []
