"""Bundled baselines on the benchmark: sanity of their ranking and exactness where expected."""
import numpy as np
import pytest

from mimicbench.benchmark.aggregate import aggregate
from mimicbench.benchmark.evaluator import run_benchmark
from mimicbench.benchmark.request import Rig, TransferRequest
from mimicbench.benchmark.results import method_dir, read_result_records
from tests.bench_fixtures import make_bench_dataset

METHODS = ["identity", "name_copy", "nearest_joint", "text_soft"]


@pytest.fixture(scope="module")
def scored(small_zoo, tmp_path_factory):
    root = tmp_path_factory.mktemp("baselines")
    data = make_bench_dataset(small_zoo, root / "data", h2h_poses=4, cct_pairs=8, cct_poses=2)
    run_benchmark(data, METHODS, ["h2h", "cct"], root / "res", progress=False)
    agg = aggregate(root / "res")
    return {p: {e["method"]: e for e in entries} for p, entries in agg["protocols"].items()}, root / "res"


def rows_of(results, name):
    version = {"identity": "1"}.get(name, "3")
    return read_result_records(method_dir(results, name, version))


def test_every_method_completes_every_case(scored):
    for protocol, entries in scored[0].items():
        for name, e in entries.items():
            assert e["complete"], (protocol, name, e["first_error"])


def test_identity_is_worst_on_h2h_and_name_copy_is_near_exact(scored):
    h2h = scored[0]["h2h"]
    assert h2h["identity"]["pmd"] == max(e["pmd"] for e in h2h.values())
    assert h2h["name_copy"]["pmd"] < 1.0
    assert h2h["identity"]["pmd"] > 5 * h2h["name_copy"]["pmd"]


def test_skeleton_methods_beat_identity_and_keep_edges(scored):
    cct, h2h = scored[0]["cct"], scored[0]["h2h"]
    for name in ("nearest_joint", "text_soft", "name_copy"):
        assert cct[name]["pmd"] < cct["identity"]["pmd"], name
        assert cct[name]["els_forward"] > 0.9
    assert h2h["text_soft"]["pmd"] < h2h["identity"]["pmd"]


def test_headline_columns_and_category_pairs_on_one_scale(scored):
    results = scored[1]
    for r in rows_of(results, "text_soft"):
        assert r.pmd == (r.pmd_height if r.protocol == "h2h" else r.pmd_extent)
        assert r.pmd_aligned is not None and r.pmd_extent <= r.pmd_height * (1 + 1e-9)
    by_pair = {}
    for r in rows_of(results, "identity"):
        if r.protocol == "cct":
            by_pair.setdefault((r.source_category, r.target_category), []).append(r.pmd_extent)
    means = np.array([np.mean(v) for v in by_pair.values()])
    assert len(means) >= 4 and means.max() <= 5 * np.median(means), dict(zip(by_pair, means.round(2)))


def _flat_pair():
    """A 2 m x 0.1 m x 0.5 m slab rigged to one bone, and a copy squashed to a tenth of its height."""
    from mimicbench.schemas.weights import SparseWeights

    corners = np.array([[x, y, z] for x in (0, 2.0) for y in (0, 0.1) for z in (0, 0.5)], np.float32)
    faces = np.array([[0, 1, 2], [1, 3, 2], [4, 6, 5], [5, 6, 7], [0, 4, 1], [1, 4, 5],
                      [2, 3, 6], [3, 7, 6], [0, 2, 4], [2, 6, 4], [1, 5, 3], [3, 5, 7]], np.int32)
    w = SparseWeights(np.zeros((8, 1), np.int32), np.ones((8, 1), np.float32), 1)
    def rig(cid, v):
        return Rig(cid, "reptile", v, faces, np.zeros((1, 3), np.float32), np.array([-1], np.int32), w, ("Root",))
    return rig("a", corners), rig("b", corners * np.float32([1, 0.1, 1]))


@pytest.mark.parametrize("name", ["name_copy", "nearest_joint", "text_soft"])
def test_root_displacement_scales_by_size_not_height(name):
    from mimicbench.benchmark.registry import get_method

    a, b = _flat_pair()
    step = np.float32([0.3, 0.0, 0.1])  # the source slides 0.3 m along its length
    req = TransferRequest(a, a.vertices + step, b, "slide", {"m_sink": np.ones((1, 1))})
    out = get_method(name).transfer([req])[0]
    # same largest extent (2 m): the target slides as far; a height ratio would make it 0.03 m
    np.testing.assert_allclose(out - b.vertices, np.broadcast_to(step, b.vertices.shape), atol=1e-5)
