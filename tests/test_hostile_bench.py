"""Hostile inputs to the benchmark, the leaderboard and pipelines (issue 31, round 3): hand-edited
and copied result rows, NaN metrics, pipeline steps that write outside the workdir or ask for
``help``, and disk-full or read-only output folders."""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from mimicbench.benchmark.aggregate import aggregate
from mimicbench.benchmark.leaderboard import write_leaderboard
from mimicbench.benchmark.results import append_results, read_run_info, write_run_info
from mimicbench.cli import main
from mimicbench.pipeline import load_pipeline, step_argv
from mimicbench.schemas.result import ResultRecord
from tests.bench_fixtures import make_bench_dataset


def row(case_id, method, pmd, version="1", status="ok", els=0.9, seconds=0.5):
    ok = status == "ok"
    v = pmd if ok else None
    return ResultRecord(case_id, "cct", method, version, status, None if ok else "failed on purpose", seconds, v, v,
                        els if ok else None, els if ok else None, "humanoid", "bird", pmd_height=v, pmd_extent=v,
                        pmd_aligned=v)


@pytest.fixture
def four_cases(tmp_path):
    """``a`` and ``b`` on 4 cct cases, PMD a: 1, 2, 3, 4 (mean 2.5), b: 10, 20, 30, 40 (mean 25)."""
    res = tmp_path / "res"
    append_results(res / "a" / "1", [row(f"c{i}", "a", float(i)) for i in range(1, 5)])
    append_results(res / "b" / "1", [row(f"c{i}", "b", 10.0 * i) for i in range(1, 5)])
    write_run_info(res, {"dataset": "nowhere", "protocols": {"cct": 4}, "case_ids": {"cct": ["c1", "c2", "c3", "c4"]}})
    return res


def _entry(agg, method):
    return next(e for e in agg["protocols"]["cct"] if e["method"] == method)


def test_hand_edited_copied_foreign_and_nan_rows_are_refused_not_averaged(four_cases, tmp_path):
    res = four_cases
    assert _entry(aggregate(res), "a")["pmd"] == pytest.approx(2.5)
    # a hand-edited row: pmd = -1 replaces c2 (stored last wins); b's NaN row replaces b's c3
    append_results(res / "a" / "1", [row("c2", "a", -1.0)])
    append_results(res / "b" / "1", [row("c3", "b", float("nan"))])
    # b's rows copied into a third method's folder; its own rows stay
    append_results(res / "c" / "1", [row(f"c{i}", "c", 5.0) for i in range(1, 5)])
    for part in sorted((res / "b" / "1").glob("part-*.parquet"))[:1]:
        shutil.copy(part, res / "c" / "1" / part.name.replace("part-0000000001", "part-0000000009"))
    # a case that is not among the run's cases
    append_results(res / "d" / "1", [row(f"c{i}", "d", 1.0) for i in range(1, 6)])
    agg = aggregate(res)
    a, b, c, d = (_entry(agg, m) for m in "abcd")
    assert a["pmd"] is None and a["invalid"] == 1 and a["missing"] == 1 and not a["complete"]
    assert b["pmd"] is None and b["invalid"] == 1
    assert c["pmd"] == pytest.approx(5.0) and c["invalid"] == 0 and c["complete"]  # the copies never replace its rows
    assert d["pmd"] is None and d["invalid"] == 1 and d["cases"] == 4
    reasons = {(r["method"], r["case_id"]): r["reason"] for r in agg["refused"]}
    assert "pmd = -1 is negative" in reasons[("a", "c2")]
    assert "pmd is NaN" in reasons[("b", "c3")]
    assert "is not among the 4 cct cases" in reasons[("d", "c5")]
    assert not any(m == "c" for m, _ in reasons)  # c has its own row for every case: the copies are never read
    md = write_leaderboard(res, tmp_path / "board", pictures=False)["md"].read_text()
    assert not re.search(r"\bnan\b", md)  # never printed as a value
    assert "### Rows not averaged" in md and "pmd = -1 is negative" in md and "+ 1 rows refused" in md
    html = (tmp_path / "board" / "leaderboard.html").read_text()
    assert "Rows not averaged" in html and ">nan<" not in html


def test_rows_copied_from_another_method_replace_nothing(four_cases):
    res = four_cases
    # identity's rows copied into nearest_joint's folder under a later sequence number
    part = next((res / "b" / "1").glob("part-*.parquet"))
    shutil.copy(part, res / "a" / "1" / part.name.replace("part-0000000001", "part-0000000007"))
    agg = aggregate(res)
    a = _entry(agg, "a")
    assert a["pmd"] == pytest.approx(2.5) and a["complete"]  # a's own cases, not b's 25
    assert agg["refused"] == []  # a has its own row for every case: the copies are never read
    # without a's own rows, the copies are shown as refused, never averaged as a's
    for p in (res / "a" / "1").glob("part-0000000001-*.parquet"):
        p.unlink()
    agg = aggregate(res)
    assert _entry(agg, "a")["pmd"] is None
    assert {r["reason"] for r in agg["refused"]} == {"a row of b v1 in the folder of a v1 (copied from another "
                                                     "method's results?)"}


def test_more_rows_than_cases_without_recorded_ids(tmp_path):
    res = tmp_path / "res"
    append_results(res / "a" / "1", [row(f"c{i}", "a", 1.0) for i in range(1, 6)])
    write_run_info(res, {"dataset": "nowhere", "protocols": {"cct": 4}})  # an older run.json: counts only
    a = _entry(aggregate(res), "a")
    assert a["pmd"] is None and a["invalid"] == 1 and not a["complete"]


def test_bench_run_records_case_ids_and_a_leaderboard_beside_its_results(small_zoo, tmp_path, capsys):
    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=1, cct_pairs=2, cct_poses=1)
    res = tmp_path / "res"
    assert main(["bench", "run", str(data), "--methods", "identity", "--out", str(res), "--quiet"]) == 0
    info = read_run_info(res)
    ids = set(pq.read_table(data / "cases", columns=["case_id"]).column("case_id").to_pylist())
    assert {c for p in info["case_ids"].values() for c in p} == ids
    before = sorted(p.relative_to(res) for p in res.rglob("*"))
    assert main(["bench", "leaderboard", str(res), "--no-pictures"]) == 0
    assert sorted(p.relative_to(res) for p in res.rglob("*")) == before  # nothing written into RESULTS
    assert (tmp_path / "res-leaderboard" / "leaderboard.md").is_file()


# --- pipelines -------------------------------------------------------------------------------------

HEAD = "[pipeline]\nname = 't'\nworkdir = 'w'\n"


@pytest.mark.parametrize("step, message", [
    ("run = 'zoo'\nout = '../../etc'\n", "outside the workdir"),
    ("run = 'zoo'\nout = '/tmp/elsewhere'\n", "outside the workdir"),
    ("run = 'zoo'\nout = 'zoo'\nhelp = true\n", "help = ... is not a step option"),
    ("run = 'zoo'\nout = 'zoo'\nhel = true\n", "hel = ... is not a step option"),  # argparse's abbreviation
    ("run = 'cases'\ndataset = '../other'\n", "outside the workdir"),
    ("run = 'leaderboard'\nresults = 'r'\nout = 'r'\n", "inside the results folder it reads"),
    ("run = 'leaderboard'\nresults = 'r'\nout = 'r/board'\n", "inside the results folder it reads"),
    ("run = 'zoo'\nout = 'z'\nallow_outside = 'yes'\n", "expected true or false"),
])
def test_pipeline_steps_writing_outside_or_asking_for_help_are_refused(tmp_path, capsys, step, message):
    path = tmp_path / "p.toml"
    path.write_text(HEAD + "[[steps]]\n" + step)
    assert main(["pipeline", str(path), "--workdir", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "mimicbench: error:" in err and message in err
    assert not (tmp_path / "etc").exists() and not Path("/tmp/elsewhere").exists()


def test_allow_outside_and_the_default_leaderboard_folder(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(HEAD + "[[steps]]\nrun = 'zoo'\nout = '../shared_zoo'\nallow_outside = true\n"
                    "[[steps]]\nrun = 'leaderboard'\nresults = 'r'\n")
    p = load_pipeline(path, workdir=tmp_path / "w")
    assert step_argv(p.steps[0], p)[:3] == ["zoo", "--out", str(tmp_path / "w" / "../shared_zoo")]
    assert "--allow-outside" not in step_argv(p.steps[0], p)
    assert step_argv(p.steps[1], p) == ["bench", "leaderboard", str(tmp_path / "w" / "r"), "--out",
                                        str(tmp_path / "w" / "r-leaderboard")]


TINY = """
[pipeline]
name = "tiny"

[[steps]]
run = "zoo"
out = "zoo"
characters = 6
clips_per_character = 1
frames_per_clip = 12
no_contact_sheet = true
quiet = true

[[steps]]
run = "cases"
dataset = "zoo"
all_pairs = true
h2h_poses = 1
cct_poses = 1
cct_pairs = 2

[[steps]]
run = "bench"
dataset = "zoo"
methods = ["identity"]
out = "results"
quiet = true

[[steps]]
run = "leaderboard"
results = "results"
no_pictures = true
"""


@pytest.mark.slow
def test_a_finished_pipeline_with_bench_and_leaderboard_redoes_nothing(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    work = tmp_path / "w"
    assert main(["pipeline", str(path), "--workdir", str(work), "--quiet"]) == 0
    first = capsys.readouterr().out
    assert first.count(" done ") == 4
    files = {p: p.stat().st_mtime_ns for p in work.rglob("*") if p.is_file()}
    assert main(["pipeline", str(path), "--workdir", str(work), "--quiet"]) == 0
    second = capsys.readouterr().out
    assert "4 skipped" in second and " done " not in second
    assert {p: p.stat().st_mtime_ns for p in work.rglob("*") if p.is_file()} == files
    assert (work / "results-leaderboard" / "leaderboard.md").is_file()
    assert not (work / "results" / "leaderboard.md").exists()


# --- disk full and read-only folders: one line naming the file and the real reason -----------------

def _full_disk_writes(monkeypatch):
    """Make every Parquet and atomic file write go to /dev/full: the kernel's real ENOSPC (Linux, as CI)."""
    assert Path("/dev/full").exists(), "this test needs Linux's /dev/full (the character device 1,7)"
    import mimicbench.schemas.manifest as manifest_mod
    import tempfile

    real_write_table = pq.write_table

    def write_table_full(table, where, *a, **k):
        if not isinstance(where, (str, os.PathLike)):
            return real_write_table(table, where, *a, **k)
        with open("/dev/full", "wb", buffering=0) as f:  # a file object: pyarrow never deletes /dev/full
            return real_write_table(table, f, *a, **k)

    monkeypatch.setattr(pq, "write_table", write_table_full)
    real_mkstemp = tempfile.mkstemp

    def full_mkstemp(*a, **k):
        fd, name = real_mkstemp(*a, **k)
        os.close(fd)
        return os.open("/dev/full", os.O_WRONLY), name

    monkeypatch.setattr(manifest_mod.tempfile, "mkstemp", full_mkstemp)


def _one_line_error(capsys, *needles):
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith("mimicbench: error: "), err
    first = err.splitlines()[0]
    for n in needles:
        assert n in first, first
    assert ".tmp: No such file" not in err
    return first


def test_a_full_disk_is_reported_with_its_reason_in_zoo_ingest_bench_and_leaderboard(small_zoo, four_cases,
                                                                                       tmp_path, monkeypatch, capsys):
    from tests.mmd_fixtures import pmx_bytes

    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=1, cct_pairs=1, cct_poses=1)
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    _full_disk_writes(monkeypatch)
    capsys.readouterr()
    assert main(["zoo", "--out", str(tmp_path / "zoo"), "--characters", "2", "--quiet"]) == 2
    _one_line_error(capsys, str(tmp_path / "zoo"), "No space left on device")
    assert main(["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(tmp_path / "ds"), "--quiet"]) == 2
    _one_line_error(capsys, str(tmp_path / "ds"), "No space left on device")
    assert main(["bench", "run", str(data), "--methods", "identity", "--out", str(tmp_path / "bench_out"), "--quiet"]) == 2
    _one_line_error(capsys, str(tmp_path / "bench_out"), "No space left on device")
    assert main(["bench", "leaderboard", str(four_cases), "--no-pictures", "--out", str(tmp_path / "board")]) == 2
    _one_line_error(capsys, str(tmp_path / "board"), "No space left on device")


def _read_only_folder(tmp_path) -> Path:
    """A folder this process cannot write into: chmod 555 for a normal user; for root (who ignores
    modes) a sysfs folder, where creating a file is refused whoever asks."""
    if os.geteuid() != 0:
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    return Path("/sys/kernel")


def test_a_read_only_output_folder_is_one_line_in_zoo_ingest_bench_and_leaderboard(small_zoo, four_cases,
                                                                                    tmp_path, capsys):
    from tests.mmd_fixtures import pmx_bytes

    ro = _read_only_folder(tmp_path)
    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=1, cct_pairs=1, cct_poses=1)
    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    capsys.readouterr()
    for argv in (["zoo", "--out", str(ro / "zoo"), "--characters", "2", "--quiet"],
                 ["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(ro / "ds"), "--quiet"],
                 ["bench", "run", str(data), "--methods", "identity", "--out", str(ro / "res"), "--quiet"],
                 ["bench", "leaderboard", str(four_cases), "--no-pictures", "--out", str(ro / "board")]):
        assert main(argv) == 2, argv
        _one_line_error(capsys, str(ro))
    assert not any((ro / n).exists() for n in ("zoo", "ds", "res", "board"))


def test_per_frame_metrics_are_range_checked_as_read_back(tmp_path):
    """Apparel rows carry per-frame lists (read back as arrays): fine values pass, a NaN or a
    negative frame is refused."""
    res = tmp_path / "res"
    rows = []
    for i, frames in enumerate(([0.5, 0.7], [0.5, float("nan")], [0.5, -0.1], [0.5, 0.6])):
        r = row(f"c{i}", "a", 0.6)
        r.protocol, r.pmd_frames, r.els_frames = "apparel", frames, [0.99, 0.98]
        rows.append(r)
    rows[3].els_frames = [0.99, 1.5]
    append_results(res / "a" / "1", rows)
    write_run_info(res, {"dataset": "nowhere", "protocols": {"apparel": 4}})
    agg = aggregate(res)
    reasons = {r["case_id"]: r["reason"] for r in agg["refused"]}
    assert reasons == {"c1": "pmd_frames is NaN", "c2": "pmd_frames = -0.1 is negative (a PMD is a mean distance, >= 0)",
                       "c3": "els_frames = 1.5 is above 1 (ELS is 1 - mean |edge ratio - 1|, at most 1)"}
    entry = agg["protocols"]["apparel"][0]
    assert (entry["ok"], entry["invalid"], entry["pmd"]) == (1, 3, None)
