"""The Ray engine gives the local engine's bytes, stage by stage, and survives killed workers.

One local Ray instance (2 CPUs) serves the whole module. The reference is the local engine's
output for the same call (sha256 of every shard), and for the failure tests a naive loop.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import signal
import sys
from functools import partial
from pathlib import Path

import numpy as np
import pytest

ray = pytest.importorskip("ray")
import cloudpickle  # noqa: E402  (ships with ray)

from mimicbench.datagen.correspond.stage import correspond_dataset  # noqa: E402
from mimicbench.engines import TaskResources, get_engine  # noqa: E402
from mimicbench.engines.ray_engine import RayEngine  # noqa: E402
from mimicbench.datagen.resample.stage import resample_dataset  # noqa: E402
from mimicbench.datagen.stage_runner import run_stage  # noqa: E402
from mimicbench.datagen.zoo.dataset import build_zoo  # noqa: E402
from mimicbench.cli import main  # noqa: E402
from mimicbench.schemas.shards import read_records  # noqa: E402

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the test's task functions travel by value


@pytest.fixture(scope="module")
def ray_instance():
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=200 << 20)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def zoos(ray_instance, tmp_path_factory):
    """The same 8-character zoo built by each engine (2 clips of 12 frames each)."""
    root = tmp_path_factory.mktemp("engines")
    kw = dict(num_characters=8, seed=3, clips_per_character=2, frames_per_clip=12, progress=False)
    build_zoo(root / "local", **kw)
    build_zoo(root / "ray", engine=RayEngine(), **kw)
    return root


def shard_hashes(root: Path, tables=("characters", "motions", "pairs")) -> dict:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for t in tables for p in sorted((root / t).glob("*.parquet"))}


def status_rows(root: Path, split: str) -> list:
    return [(s.asset, s.stage, s.status, s.reason) for s in read_records(root, "status", split)]


def test_zoo_on_ray_is_byte_identical(zoos):
    local, on_ray = shard_hashes(zoos / "local"), shard_hashes(zoos / "ray")
    assert local and local == on_ray
    assert (zoos / "local" / "CARD.md").read_bytes() == (zoos / "ray" / "CARD.md").read_bytes()
    assert shard_hashes(zoos / "local", ("status",)) == shard_hashes(zoos / "ray", ("status",))


def test_resample_on_ray_is_byte_identical(zoos):
    for name, engine in (("local", None), ("ray", RayEngine())):
        s = resample_dataset(zoos / name, zoos / f"{name}5k", faces=1000, progress=False, engine=engine,
                             flush_every=3)
        assert s["failed"] == 0 and s["resampled"] == 8
    assert shard_hashes(zoos / "local5k") == shard_hashes(zoos / "ray5k")
    assert status_rows(zoos / "local5k", "resample") == status_rows(zoos / "ray5k", "resample")


def test_correspond_on_ray_is_byte_identical_in_blocks(zoos):
    for name, engine in (("local5k", None), ("ray5k", RayEngine())):
        s = correspond_dataset(zoos / name, all_pairs=True, progress=False, engine=engine, block=5)
        assert s["failed_blocks"] == []
    hashes = shard_hashes(zoos / "local5k", ("pairs",))
    assert hashes and hashes == shard_hashes(zoos / "ray5k", ("pairs",))
    # every ordered pair of each split, in sampled order (a naive double loop over sorted IDs)
    chars = read_records(zoos / "local5k", "characters")
    pairs = read_records(zoos / "ray5k", "pairs")
    expect = [(a.character_id, b.character_id) for split in ("train", "val", "test")
              for a in sorted((c for c in chars if c.split == split), key=lambda c: c.character_id)
              for b in sorted((c for c in chars if c.split == split), key=lambda c: c.character_id) if a is not b]
    assert sorted((p.source_id, p.target_id) for p in pairs) == sorted(expect)


def test_apparel_on_ray_is_byte_identical(ray_instance, tmp_path):
    from mimicbench.datagen.apparel.stage import simulate_dataset

    zoo = tmp_path / "zoo"
    build_zoo(zoo, 1, seed=0, categories=["apparel"], clips_per_character=1, frames_per_clip=12, progress=False)
    for name, engine in (("local", None), ("ray", RayEngine())):
        s = simulate_dataset(zoo, tmp_path / name, physics_fps=60.0, relax=2, progress=False, engine=engine)
        assert s["simulated"] == 1 and s["failed"] == 0
    assert shard_hashes(tmp_path / "local", ("characters", "motions")) == \
        shard_hashes(tmp_path / "ray", ("characters", "motions"))


class KillOnce:
    """Wraps a stage function: the first call on ``victim`` SIGKILLs its own worker process."""

    def __init__(self, fn, victim: int, marker: str):
        self.fn, self.victim, self.marker = fn, victim, marker

    def __call__(self, item):
        if item == self.victim and not os.path.exists(self.marker):
            Path(self.marker).write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
        return self.fn(item)


def zoo_character_bytes(i: int) -> bytes:
    """One zoo character's rest vertices and first clip, as bytes (a deterministic real stage result)."""
    from mimicbench.datagen.zoo.build import build_character
    from mimicbench.datagen.zoo.plan import plan_zoo

    built = build_character(plan_zoo(6, seed=1)[i], "train", 1, 10)
    return built.record.vertices.tobytes() + built.motions[0].transforms.tobytes()


def test_a_killed_worker_is_retried_with_identical_output(ray_instance, tmp_path):
    marker = tmp_path / "killed"
    expect = [zoo_character_bytes(i) for i in range(6)]  # the naive loop
    results, statuses = run_stage(list(range(6)), KillOnce(zoo_character_bytes, 2, str(marker)), "zoo",
                                  engine=RayEngine(max_retries=2), chunk=2, progress=False)
    assert marker.exists() and int(marker.read_text()) != os.getpid()  # a worker, not this process, died
    assert [s.status for s in statuses] == ["ok"] * 6
    assert results == expect


def always_dies(item):
    if item == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return item * 10


def test_a_task_failing_for_good_is_a_status_row(ray_instance):
    results, statuses = run_stage(list(range(4)), always_dies, "unit", name_of=lambda i: f"item{i}",
                                  engine=RayEngine(max_retries=1), progress=False)
    assert results == [0, 20, 30]
    assert [s.status for s in statuses] == ["ok", "failed", "ok", "ok"]
    assert "WorkerCrashedError" in statuses[1].reason and "1 retries" in statuses[1].reason


def test_ordered_delivery_and_resources(ray_instance):
    seen = []
    run_stage(list(range(9)), partial(pow, 2), "unit", engine=RayEngine(max_in_flight=2), chunk=2, progress=False,
              ordered=True, on_done=lambda i, ok, r: seen.append((i, r)),
              resources=TaskResources(num_cpus=1, memory=64 << 20))
    assert seen == [(i, 2 ** i) for i in range(9)]
    with pytest.raises(ValueError, match="num_cpus"):
        TaskResources(num_cpus=0)
    with pytest.raises(ValueError, match="engine"):
        get_engine("spark")
    with pytest.raises(ValueError, match="ray-address"):
        get_engine("local", address="auto")


def test_cli_stages_take_the_engine(ray_instance, zoos, tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["zoo", "--out", str(out), "--characters", "8", "--seed", "3", "--clips-per-character", "2",
                 "--frames-per-clip", "12", "--engine", "ray", "--quiet", "--no-contact-sheet"]) == 0
    assert shard_hashes(out) == shard_hashes(zoos / "local")
    assert main(["datagen", "resample", str(zoos / "local"), str(tmp_path / "r"), "--engine", "local",
                 "--ray-address", "auto"]) == 2
    assert "only with --engine ray" in capsys.readouterr().err


def test_bench_run_on_ray_gives_the_local_rows(zoos, tmp_path):
    """Results rows of `bench run --engine ray` equal the local engine's (worker processes), all but seconds."""
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.results import method_dir, read_result_records
    from tests.bench_fixtures import make_bench_dataset

    data = make_bench_dataset(zoos / "local", tmp_path / "data", h2h_poses=2, cct_pairs=4, cct_poses=2)
    methods = ["identity", "name_copy", "nearest_joint"]
    local = run_benchmark(data, methods, ["h2h", "cct"], tmp_path / "local", batch_size=3, progress=False)
    on_ray = run_benchmark(data, methods, ["h2h", "cct"], tmp_path / "ray", batch_size=3, progress=False,
                           engine=RayEngine())
    assert local["computed"] == on_ray["computed"] > 0 and on_ray["failed"] == 0

    from mimicbench.benchmark.registry import get_method

    version = {m: get_method(m).metadata.version for m in methods}

    def rows(root):
        out = []
        for m in methods:
            for r in read_result_records(method_dir(root, m, version[m])):
                out.append(dataclasses.replace(r, seconds=0.0))
        return sorted(out, key=lambda r: (r.method, r.case_id))

    assert rows(tmp_path / "local") == rows(tmp_path / "ray")
    # the sampled cases' predictions for the leaderboard pictures are kept on Ray too, byte for byte
    for m in methods:
        v = version[m]
        a = sorted((method_dir(tmp_path / "local", m, v) / "samples").rglob("*.npz"))
        b = sorted((method_dir(tmp_path / "ray", m, v) / "samples").rglob("*.npz"))
        assert [p.name for p in a] == [p.name for p in b]
        assert all(np.array_equal(np.load(x)[k], np.load(y)[k]) for x, y in zip(a, b) for k in np.load(x).files)


@pytest.mark.slow
@pytest.mark.blender
def test_ingest_on_ray_is_byte_identical(ray_instance, assets_dir, tmp_path):
    """Real glTF assets through Blender: a Ray task an asset (its worker's own Blender) gives the local shards."""
    pytest.importorskip("bpy")
    from mimicbench.datagen.ingest.runner import ingest_assets

    assets = [assets_dir / "glb" / n for n in ("Fox.glb", "Quaternius_Rat.glb", "CesiumMan.glb")]
    for name, engine in (("local", None), ("ray", RayEngine())):
        s = ingest_assets(assets, tmp_path / name, progress=False, engine=engine)
        assert s["failed"] == 0 and s["characters"] == 3
    assert shard_hashes(tmp_path / "local", ("characters", "motions")) == \
        shard_hashes(tmp_path / "ray", ("characters", "motions"))


def test_bench_run_on_ray_has_the_local_per_case_timeout(zoos, tmp_path):
    """A method hanging on one case, exiting on another and raising on a third: `bench run --engine ray`
    writes the local engine's rows for them ("timed out after 2 s", ...) and scores their batch-mates."""
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.registry import register
    from mimicbench.benchmark.results import method_dir, read_result_records
    from tests.bench_fixtures import make_bench_dataset
    from tests.hostile_methods import ENV, HostileMethod, hostile_env

    data = make_bench_dataset(zoos / "local", tmp_path / "data", h2h_poses=1, cct_pairs=3, cct_poses=2)
    cct = [c.case_id for c in read_records(data, "cases", "cct")]
    assert len(cct) >= 5
    acts = {cct[0]: "hang", cct[2]: "exit", cct[4]: "raise"}
    register("hostile", HostileMethod)
    os.environ[ENV] = hostile_env(acts)  # the local engine's worker reads it from this process
    try:
        local = run_benchmark(data, ["hostile"], ["cct"], tmp_path / "local", batch_size=2, progress=False,
                              case_timeout=2)
        on_ray = run_benchmark(data, ["hostile"], ["cct"], tmp_path / "ray", batch_size=2, progress=False,
                               case_timeout=2, engine=RayEngine(runtime_env={"env_vars": {ENV: os.environ[ENV]}}))
    finally:
        del os.environ[ENV]
    assert local["failed"] == on_ray["failed"] == len(acts)

    def rows(root):
        return {r.case_id: dataclasses.replace(r, seconds=0.0) for r in read_result_records(method_dir(root, "hostile", "1"))}

    ray_rows = rows(tmp_path / "ray")
    assert ray_rows == rows(tmp_path / "local") and set(ray_rows) == set(cct)
    assert ray_rows[cct[0]].status == "failed" and "timed out after 2 s" in ray_rows[cct[0]].error
    assert "method called sys.exit(3)" in ray_rows[cct[2]].error
    assert "method raised: RuntimeError: hostile failure" in ray_rows[cct[4]].error
    assert all(ray_rows[c].status == "ok" for c in cct if c not in acts)
