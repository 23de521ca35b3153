"""The evaluator: failures recorded per case, no partial averages, resume, torchrun parity."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mimicbench.benchmark.aggregate import aggregate
from mimicbench.benchmark.evaluator import run_benchmark
from mimicbench.benchmark.registry import get_method, register
from mimicbench.benchmark.results import method_dir, read_result_records
from mimicbench.schemas.shards import read_records
from tests.bench_fixtures import FlakyMethod, KillerCopy, make_bench_dataset

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench_data(small_zoo, tmp_path_factory):
    return make_bench_dataset(small_zoo, tmp_path_factory.mktemp("bench") / "data")


def rows_by_case(results, name, version="1"):
    return {r.case_id: r for r in read_result_records(method_dir(results, name, version))}


def test_method_raising_every_third_case_fails_exactly_those(bench_data, tmp_path):
    register("flaky", FlakyMethod)
    h2h = read_records(bench_data, "cases", "h2h")
    assert len(h2h) >= 6
    run_benchmark(bench_data, ["flaky"], ["h2h"], tmp_path, batch_size=1, progress=False)
    rows = rows_by_case(tmp_path, "flaky")
    failed = sorted(i for i, c in enumerate(h2h) if rows[c.case_id].status == "failed")
    assert failed == [i for i in range(len(h2h)) if (i + 1) % 3 == 0]
    assert all("flaky failure" in rows[h2h[i].case_id].error for i in failed)
    assert all(rows[c.case_id].pmd is None for i, c in enumerate(h2h) if i in failed)
    entry = aggregate(tmp_path)["protocols"]["h2h"][0]
    assert entry["failed"] == len(failed) and entry["pmd"] is None and entry["els"] is None


def test_batched_failures_are_isolated_and_nan_or_shape_fail_with_reason(bench_data, tmp_path):
    h2h = read_records(bench_data, "cases", "h2h")

    class Flaky2(FlakyMethod):
        def __init__(self):
            super().__init__()
            self.nan_cases = {h2h[0].case_id}
            self.bad_shape = {h2h[1].case_id}

    register("flaky", Flaky2)
    run_benchmark(bench_data, ["flaky"], ["h2h"], tmp_path, batch_size=4, progress=False)
    rows = rows_by_case(tmp_path, "flaky")
    assert len(rows) == len(h2h)
    assert "NaN" in rows[h2h[0].case_id].error
    assert "wrong shape" in rows[h2h[1].case_id].error
    assert sum(r.status == "ok" for r in rows.values()) >= len(h2h) // 3


def test_missing_cases_give_no_average(bench_data, tmp_path):
    run_benchmark(bench_data, ["identity"], ["h2h"], tmp_path, progress=False)
    folder = method_dir(tmp_path, "identity", "1")
    parts = sorted(folder.glob("part-*.parquet"))
    entry = aggregate(tmp_path)["protocols"]["h2h"][0]
    assert entry["complete"] and entry["pmd"] is not None
    # drop a part file: its cases are now missing
    import pyarrow.parquet as pq

    t = pq.read_table(parts[0])
    pq.write_table(t.slice(1), parts[0])
    entry = aggregate(tmp_path)["protocols"]["h2h"][0]
    assert entry["missing"] == 1 and entry["pmd"] is None


def test_killed_run_resumes_to_the_same_results(bench_data, tmp_path):
    script = (
        "import sys; sys.path.insert(0, %r)\n"
        "from mimicbench.benchmark.registry import register\nfrom tests.bench_fixtures import KillerCopy\n"
        "from mimicbench.benchmark.evaluator import run_benchmark\nregister('killer', KillerCopy)\n"
        "run_benchmark(%r, ['killer'], ['h2h', 'cct'], %r, batch_size=2, progress=False, in_process=True)\n"
    ) % (str(REPO), str(bench_data), str(tmp_path / "killed"))
    env = dict(os.environ, KILL_AFTER_BATCHES="3")
    proc = subprocess.run([sys.executable, "-c", script], env=env, cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 17, proc.stderr
    partial = rows_by_case(tmp_path / "killed", "killer")
    assert 0 < len(partial) < len(read_records(bench_data, "cases"))
    register("killer", KillerCopy)
    summary = run_benchmark(bench_data, ["killer"], ["h2h", "cct"], tmp_path / "killed", batch_size=2, progress=False)
    assert summary["skipped"] == len(partial)
    run_benchmark(bench_data, ["killer"], ["h2h", "cct"], tmp_path / "straight", batch_size=2, progress=False)
    a, b = rows_by_case(tmp_path / "killed", "killer"), rows_by_case(tmp_path / "straight", "killer")
    assert a.keys() == b.keys()
    for cid in a:
        assert a[cid].status == b[cid].status
        for m in ("pmd", "pmd_squared", "els", "els_forward"):
            assert (getattr(a[cid], m) is None) == (getattr(b[cid], m) is None)
            if getattr(a[cid], m) is not None:
                assert np.isclose(getattr(a[cid], m), getattr(b[cid], m), rtol=1e-9)


@pytest.mark.slow
def test_torchrun_two_processes_give_the_same_aggregate(bench_data, tmp_path):
    torchrun = Path(sys.executable).with_name("torchrun")
    cmd = [str(torchrun), "--standalone", "--nproc-per-node", "2", "-m", "mimicbench", "bench", "run",
           str(bench_data), "--methods", "name_copy,identity", "--out", str(tmp_path / "dist"), "--quiet"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    run_benchmark(bench_data, ["name_copy", "identity"], ["h2h", "cct"], tmp_path / "single", progress=False)
    version = get_method("name_copy").metadata.version
    parts = list(method_dir(tmp_path / "dist", "name_copy", version).glob("part-*-r001-*.parquet"))
    assert parts, "rank 1 wrote no results"
    da, sa = aggregate(tmp_path / "dist"), aggregate(tmp_path / "single")
    for protocol in ("h2h", "cct"):
        for d, s in zip(da["protocols"][protocol], sa["protocols"][protocol]):
            assert (d["method"], d["cases"], d["failed"]) == (s["method"], s["cases"], s["failed"])
            for m in ("pmd", "els"):
                assert np.isclose(d[m], s[m], rtol=1e-9)
