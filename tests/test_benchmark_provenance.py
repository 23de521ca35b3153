"""Results know what made them, keep their stored order and survive bad parts (issue 12, items 3, 5,
8 and 10): meta.json, cases tied to the dataset state, no mixing, sequence-numbered parts, umask,
0-byte parts skipped."""
import hashlib
import json
import logging
import os
import shutil
import subprocess
from dataclasses import asdict, replace

import pyarrow.parquet as pq
import pytest

from mimicbench.baselines.identity import Identity
from mimicbench.baselines.name_copy import NameCopy
from mimicbench.benchmark.aggregate import aggregate
from mimicbench.benchmark.cases import build_cases, write_cases
from mimicbench.benchmark.evaluator import run_benchmark
from mimicbench.benchmark.provenance import META_FILE, ProvenanceError, check_results_provenance
from mimicbench.benchmark.registry import register
from mimicbench.benchmark.results import done_case_ids, method_dir, part_files, read_result_records
from mimicbench import __version__
from mimicbench.schemas.fingerprint import files_fingerprint, table_fingerprint
from mimicbench.schemas.manifest import load_manifest, sha256_of
from mimicbench.schemas.shards import read_records
from mimicbench.schemas.validate import validate_dataset
from tests.bench_fixtures import make_bench_dataset
from tests.hostile_methods import ENV, HostileMethod, hostile_env


@pytest.fixture(scope="module")
def bench_data(small_zoo, tmp_path_factory):
    return make_bench_dataset(small_zoo, tmp_path_factory.mktemp("prov") / "data", h2h_poses=2, cct_pairs=3,
                              cct_poses=1)


def copy_dataset(src, dest):
    shutil.copytree(src, dest)
    return dest


def case_shards(dataset):
    m = load_manifest(dataset)
    return {s["path"]: s["sha256"] for s in m["tables"]["cases"]["shards"]}


def test_meta_json_records_fingerprints_metadata_and_version(bench_data, tmp_path):
    run_benchmark(bench_data, ["identity"], ["h2h", "cct"], tmp_path, progress=False)
    meta = json.loads((method_dir(tmp_path, "identity", "1") / META_FILE).read_text())
    assert set(meta) == {"method", "toolkit_version", "dataset", "fingerprints", "weights", "created"}
    assert meta["weights"] is None  # identity has no weights
    assert meta["method"] == json.loads(json.dumps(asdict(Identity.metadata)))
    assert meta["toolkit_version"] == __version__ and meta["dataset"] == str(bench_data)
    fps = meta["fingerprints"]
    assert fps["characters"] == table_fingerprint(bench_data, "characters")
    assert fps["motions"] == table_fingerprint(bench_data, "motions")
    assert fps["pairs"] is None
    assert set(fps["cases"]) == {"h2h", "cct"} and fps["cases"]["h2h"] != fps["cases"]["cct"]
    # the cases record the tables they were built from
    recorded = load_manifest(bench_data)["configs"]["cases"]["fingerprint"]["inputs"]
    assert recorded == {"characters": fps["characters"], "motions": fps["motions"]}
    assert check_results_provenance(tmp_path)["characters"] == fps["characters"]


def test_cases_of_a_regenerated_zoo_are_refused(bench_data, tmp_path, capsys):
    """Issue: cases built from an earlier zoo were scored against a regenerated one (name_copy 7.9
    instead of 0.47) and validate said OK."""
    from mimicbench.datagen.zoo.dataset import build_zoo

    data = copy_dataset(bench_data, tmp_path / "data")
    build_zoo(data, 14, seed=1, progress=False)  # regenerate in place: the old cases stay behind
    assert "warning:" in (err := capsys.readouterr().err) and "table 'cases' was made from other" in err
    with pytest.raises(ProvenanceError, match="made from other characters, motions than.*dataset changed.*bench cases"):
        run_benchmark(data, ["name_copy"], ["h2h", "cct"], tmp_path / "res", progress=False)
    assert not (tmp_path / "res").exists()  # refused before writing anything
    assert any("table 'cases' was made from other characters, motions" in p for p in validate_dataset(data))
    write_cases(data, build_cases(data, "all", h2h_pairs=4, h2h_poses=2, cct_pairs=3, cct_poses=1), {"stage": "t"})
    assert validate_dataset(data) == []
    run_benchmark(data, ["name_copy"], ["h2h"], tmp_path / "res", progress=False)
    rows = read_result_records(method_dir(tmp_path / "res", "name_copy", NameCopy.metadata.version))
    assert rows and all(r.status == "ok" and r.pmd < 1.0 for r in rows)  # scored on its own zoo again


def test_cases_without_recorded_inputs_are_refused(bench_data, tmp_path):
    data = copy_dataset(bench_data, tmp_path / "data")
    manifest = json.loads((data / "manifest.json").read_text())
    del manifest["configs"]["cases"]["fingerprint"]
    (data / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(ProvenanceError, match="do not record which characters and motions"):
        run_benchmark(data, ["identity"], ["h2h"], tmp_path / "res", progress=False)


def test_results_of_another_dataset_are_not_resumed_or_mixed(bench_data, tmp_path):
    """Issue: `bench run` into a results folder made from another dataset reused the old rows."""
    other = copy_dataset(bench_data, tmp_path / "other")
    write_cases(other, build_cases(other, "test", h2h_pairs=4, h2h_poses=2, cct_pairs=3, cct_poses=1, seed=7),
                {"stage": "t"})
    res = tmp_path / "res"
    run_benchmark(bench_data, ["identity"], ["h2h"], res, progress=False)
    before = {p.name: sha256_of(p) for p in part_files(method_dir(res, "identity", "1"))}
    for methods in (["identity"], ["name_copy"]):  # the same method, or another one into the same folder
        with pytest.raises(ProvenanceError, match="another dataset state.*cases/h2h"):
            run_benchmark(other, methods, ["h2h"], res, progress=False)
    assert {p.name: sha256_of(p) for p in part_files(method_dir(res, "identity", "1"))} == before
    assert not method_dir(res, "name_copy", NameCopy.metadata.version).exists()
    # a results folder assembled from two runs on different dataset states is refused by the leaderboard
    run_benchmark(other, ["name_copy"], ["h2h"], tmp_path / "res2", progress=False)
    shutil.copytree(tmp_path / "res2" / "name_copy", res / "name_copy")
    with pytest.raises(ProvenanceError, match="different dataset states.*cases/h2h"):
        check_results_provenance(res)
    from mimicbench.benchmark.leaderboard import write_leaderboard

    with pytest.raises(ProvenanceError):
        write_leaderboard(res)


class WeightedIdentity(Identity):
    """Identity that says it loads the weights file named by WEIGHTED_IDENTITY_FILE."""

    metadata = replace(Identity.metadata, name="weighted_identity")

    def weights_fingerprint(self):
        return files_fingerprint({"weights": os.environ["WEIGHTED_IDENTITY_FILE"]})


def run_weighted(bench_data, res, weights, content: bytes, monkeypatch):
    """Score ``weighted_identity`` into ``res`` with its weights file ``weights`` holding ``content``;
    returns its results folder."""
    register("weighted_identity", WeightedIdentity)
    weights.write_bytes(content)
    monkeypatch.setenv("WEIGHTED_IDENTITY_FILE", str(weights))
    run_benchmark(bench_data, ["weighted_identity"], ["h2h"], res, progress=False, in_process=True)
    return method_dir(res, "weighted_identity", Identity.metadata.version)


def test_rows_made_with_other_weights_are_not_resumed_or_mixed(bench_data, tmp_path, monkeypatch):
    """A user's checkpoint (given by environment variable) must not add rows to the folder of the
    shipped weights' rows of the same method version, nor resume from them."""
    weights, res = tmp_path / "weights.safetensors", tmp_path / "res"
    folder = run_weighted(bench_data, res, weights, b"shipped", monkeypatch)
    meta = json.loads((folder / META_FILE).read_text())
    name_sha = json.dumps({"weights": hashlib.sha256(b"shipped").hexdigest()}, separators=(",", ":"))
    assert meta["weights"] == hashlib.sha256(name_sha.encode()).hexdigest()
    before = {p.name: sha256_of(p) for p in part_files(folder)}
    run_benchmark(bench_data, ["weighted_identity"], ["h2h"], res, progress=False, in_process=True)  # same weights: resumes
    weights.write_bytes(b"retrained")
    with pytest.raises(ProvenanceError, match="other weights.*this run loads"):
        run_benchmark(bench_data, ["weighted_identity"], ["h2h"], res, progress=False, in_process=True)
    assert {p.name: sha256_of(p) for p in part_files(folder)} == before
    assert json.loads((folder / META_FILE).read_text())["weights"] == meta["weights"]
    # a copy of the weights under another folder is the same weights
    (tmp_path / "copy").mkdir()
    run_weighted(bench_data, res, tmp_path / "copy" / "weights.safetensors", b"shipped", monkeypatch)


def test_results_without_recorded_weights_are_refused_for_a_method_with_weights(bench_data, tmp_path, monkeypatch):
    res = tmp_path / "res"
    path = run_weighted(bench_data, res, tmp_path / "w.bin", b"w", monkeypatch) / META_FILE
    meta = json.loads(path.read_text())
    del meta["weights"]  # as written by an older toolkit
    path.write_text(json.dumps(meta))
    with pytest.raises(ProvenanceError, match="no weights recorded"):
        run_benchmark(bench_data, ["weighted_identity"], ["h2h"], res, progress=False, in_process=True)


def test_files_fingerprint_is_by_name_and_content_not_folder(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for d in ("a", "b"):
        (tmp_path / d / "x.safetensors").write_bytes(b"1")
        (tmp_path / d / "y.safetensors").write_bytes(b"2")
    fa = files_fingerprint({"y": tmp_path / "a" / "y.safetensors", "x": tmp_path / "a" / "x.safetensors"})
    assert fa == files_fingerprint({"x": tmp_path / "b" / "x.safetensors", "y": tmp_path / "b" / "y.safetensors"})
    assert fa != files_fingerprint({"x": tmp_path / "b" / "y.safetensors", "y": tmp_path / "b" / "x.safetensors"})
    (tmp_path / "b" / "y.safetensors").write_bytes(b"3")
    assert fa != files_fingerprint({"x": tmp_path / "b" / "x.safetensors", "y": tmp_path / "b" / "y.safetensors"})
    with pytest.raises(ValueError, match="at least one"):
        files_fingerprint({})


def test_parts_without_meta_json_are_refused(bench_data, tmp_path):
    run_benchmark(bench_data, ["identity"], ["h2h"], tmp_path, progress=False)
    (method_dir(tmp_path, "identity", "1") / META_FILE).unlink()
    with pytest.raises(ProvenanceError, match="without meta.json"):
        run_benchmark(bench_data, ["identity"], ["h2h"], tmp_path, progress=False)
    assert check_results_provenance(tmp_path) == {}  # the leaderboard shows it, provenance unknown


def test_copied_results_folder_keeps_the_retried_rows(bench_data, tmp_path, monkeypatch):
    """Issue: after --retry-failed, a plain `cp -r` of the results folder brought back the stale
    failed rows (the copy's modification times decided which row won)."""
    h2h = [c.case_id for c in read_records(bench_data, "cases", "h2h")]
    register("hostile", HostileMethod)
    monkeypatch.setenv(ENV, hostile_env({h2h[0]: "raise", h2h[2]: "raise"}))
    res = tmp_path / "res"
    run_benchmark(bench_data, ["hostile"], ["h2h"], res, batch_size=len(h2h), progress=False, in_process=True)
    folder = method_dir(res, "hostile", "1")
    [failed_part] = part_files(folder)
    monkeypatch.setenv(ENV, "")
    summary = run_benchmark(bench_data, ["hostile"], ["h2h"], res, progress=False, retry_failed=True,
                            in_process=True)
    assert summary["computed"] == 2
    subprocess.run(["cp", "-r", str(res), str(tmp_path / "copy")], check=True)
    copy = method_dir(tmp_path / "copy", "hostile", "1")
    # cp -r stamps the copies in directory order: make the stale part the newest, as it can happen
    os.utime(copy / failed_part.name, (4e9, 4e9))
    newest = max(copy.glob("part-*.parquet"), key=lambda p: p.stat().st_mtime_ns)
    assert newest.name == failed_part.name  # modification order would pick the failed rows
    rows = {r.case_id: r for r in read_result_records(copy)}
    assert all(r.status == "ok" for r in rows.values()) and len(rows) == len(h2h)
    assert done_case_ids(copy, include_failed=False) == set(h2h)
    assert aggregate(tmp_path / "copy")["protocols"]["h2h"][0]["complete"]


def test_parts_are_fsynced_files_with_the_users_umask(bench_data, tmp_path):
    old = os.umask(0o002)
    try:
        run_benchmark(bench_data, ["identity"], ["h2h"], tmp_path, batch_size=4, progress=False, in_process=True)
    finally:
        os.umask(old)
    folder = method_dir(tmp_path, "identity", "1")
    files = part_files(folder) + [folder / META_FILE, tmp_path / "run.json"]
    assert len(files) >= 3
    for f in files:
        assert f.stat().st_mode & 0o777 == 0o664, f
    assert not list(folder.glob(".*"))  # no temporary left behind


def test_empty_and_damaged_parts_are_reported_and_skipped(bench_data, tmp_path, caplog):
    """Issue: a 0-byte result part blocked `bench run` and `leaderboard`."""
    from mimicbench.cli import main

    res = tmp_path / "res"
    run_benchmark(bench_data, ["identity"], ["h2h"], res, batch_size=2, progress=False, in_process=True)
    folder = method_dir(res, "identity", "1")
    parts = part_files(folder)
    lost = set(pq.read_table(parts[0]).column("case_id").to_pylist())
    parts[0].write_bytes(b"")  # 0 bytes (a full disk, a crash before the data reached it)
    (folder / "part-0000000099-r000-0123456789ab.parquet").write_bytes(b"PAR1 not parquet")
    with caplog.at_level(logging.WARNING, logger="mimicbench"):
        assert aggregate(res)["protocols"]["h2h"][0]["missing"] == len(lost)
        assert main(["bench", "leaderboard", str(res)]) == 0
        summary = run_benchmark(bench_data, ["identity"], ["h2h"], res, batch_size=2, progress=False,
                                in_process=True)
    assert f"{parts[0]}: skipped (empty file, 0 bytes)" in caplog.text
    assert "part-0000000099-r000-0123456789ab.parquet: skipped (not a readable result part" in caplog.text
    assert summary["computed"] == len(lost)  # recomputed, nothing else redone
    assert aggregate(res)["protocols"]["h2h"][0]["complete"]


def test_cases_split_bogus_and_empty_results_keep_the_cases(bench_data, tmp_path, capsys):
    """Issue: `bench cases --split bogus` wiped 60 cases."""
    from mimicbench.cli import main

    data = copy_dataset(bench_data, tmp_path / "data")
    before = case_shards(data)
    with pytest.raises(SystemExit) as exc:
        main(["bench", "cases", str(data), "--split", "bogus"])
    assert exc.value.code == 2 and "invalid choice: 'bogus'" in capsys.readouterr().err
    assert main(["bench", "cases", str(data), "--h2h-pairs", "0", "--cct-pairs", "0"]) == 2
    assert "mimicbench: error: " in (err := capsys.readouterr().err) and "no cases were made" in err
    assert "(--split all)" in err  # the test split was used: another split may have cases
    assert main(["bench", "cases", str(data), "--split", "all", "--h2h-pairs", "0", "--cct-pairs", "0"]) == 2
    assert "no cases were made" in (err := capsys.readouterr().err) and "--split all" not in err  # already all
    with pytest.raises(ValueError, match="no cases were made"):
        write_cases(data, build_cases(data, "bogus"), {"stage": "t"})
    assert case_shards(data) == before
    assert all((data / p).exists() for p in before)


@pytest.mark.parametrize("argv, message", [
    (["--batch-size", "0"], "--batch-size: expected an integer >= 1, got '0'"),
    (["--batch-size", "-1"], "--batch-size: expected an integer >= 1, got '-1'"),
    (["--case-timeout", "0"], "--case-timeout: expected a finite number > 0, got '0'"),
    (["--methods", ""], "--methods: expected a comma-separated list of at least one method name"),
    (["--methods", " , "], "--methods: expected a comma-separated list of at least one method name"),
    (["--protocols", "h2h,bogus"], "--protocols: unknown 'bogus'"),
])
def test_bench_run_options_are_range_checked(bench_data, tmp_path, capsys, argv, message):
    from mimicbench.cli import main

    args = ["bench", "run", str(bench_data), "--out", str(tmp_path / "res"), "--methods", "identity"] + argv
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "res").exists()
