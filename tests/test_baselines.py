"""Bundled baselines on the benchmark: sanity of their ranking and exactness where expected."""
import numpy as np
import pytest

from benchmark.aggregate import aggregate
from benchmark.evaluator import run_benchmark
from tests.bench_fixtures import make_bench_dataset


@pytest.fixture(scope="module")
def scored(small_zoo, tmp_path_factory):
    root = tmp_path_factory.mktemp("baselines")
    data = make_bench_dataset(small_zoo, root / "data", h2h_poses=4, cct_pairs=8, cct_poses=2)
    run_benchmark(data, ["identity", "name_copy", "nearest_joint", "text_soft"], ["h2h", "cct"], root / "res",
                  progress=False)
    agg = aggregate(root / "res")
    return {p: {e["method"]: e for e in entries} for p, entries in agg["protocols"].items()}


def test_every_method_completes_every_case(scored):
    for protocol, entries in scored.items():
        for name, e in entries.items():
            assert e["complete"], (protocol, name, e["first_error"])


def test_identity_is_worst_on_h2h_and_name_copy_is_near_exact(scored):
    h2h = scored["h2h"]
    assert h2h["identity"]["pmd"] == max(e["pmd"] for e in h2h.values())
    assert h2h["name_copy"]["pmd"] < 1.0
    assert h2h["identity"]["pmd"] > 5 * h2h["name_copy"]["pmd"]


def test_skeleton_methods_beat_identity_and_keep_edges(scored):
    assert scored["cct"]["nearest_joint"]["pmd"] < scored["cct"]["identity"]["pmd"]
    assert scored["h2h"]["text_soft"]["pmd"] < scored["h2h"]["identity"]["pmd"]
    for name in ("nearest_joint", "text_soft", "name_copy"):
        assert scored["cct"][name]["els_forward"] > 0.9
