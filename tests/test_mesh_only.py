"""A method that declares it reads meshes only (``MethodMetadata.reads_rig`` False) gets requests
without the rig, on both legs of the cycle, while the evaluator still scores with the full rigs."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.benchmark.batch import evaluate_batch
from mimicbench.benchmark.evaluator import load_cases
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.benchmark.protocols.base import EvalData
from mimicbench.benchmark.request import MeshOnlyRig, MotionRequest, Rig, RigWithheld, TransferRequest, mesh_only
from mimicbench.schemas.weights import SparseWeights


class MeshRecorder(PoseTransferMethod):
    """Records every request it is given; answers the target's rest mesh moved by 1 cm (reads no rig)."""

    metadata = MethodMetadata(name="mesh_recorder", version="1", reads_rig=False)

    def __init__(self):
        self.got = []

    def transfer(self, requests):
        self.got.extend(requests)
        return [np.asarray(r.target.vertices) + np.float32(0.01) for r in requests]


class RigRecorder(MeshRecorder):
    metadata = MethodMetadata(name="rig_recorder", version="1")


class ClaimsMeshOnlyReadsBones(PoseTransferMethod):
    """Declares meshes only, then reads the target's keypoints."""

    metadata = MethodMetadata(name="liar", version="1", reads_rig=False)

    def transfer(self, requests):
        return [np.asarray(r.target.vertices) + r.target.keypoints.mean() for r in requests]


@pytest.fixture(scope="module")
def bench(small_zoo, tmp_path_factory):
    from tests.bench_fixtures import make_bench_dataset

    root = make_bench_dataset(small_zoo, tmp_path_factory.mktemp("meshonly") / "data", h2h_poses=1, cct_pairs=2,
                              cct_poses=1)
    cases = load_cases(root, ["h2h", "cct"])
    return {p: c[:3] for p, c in cases.items()}, EvalData.load(root)


def test_mesh_only_requests_carry_no_bones_on_both_legs(bench):
    cases, data = bench
    mesh, rig = MeshRecorder(), RigRecorder()
    for protocol in ("cct", "h2h"):
        rows_mesh = evaluate_batch(mesh, protocol, cases[protocol], data)
        rows_rig = evaluate_batch(rig, protocol, cases[protocol], data)
        for a, b in zip(rows_mesh, rows_rig):  # the same answers scored the same: the scores use the full rigs
            assert a.status == b.status == "ok", (a.error, b.error)
            for col in ("pmd", "pmd_extent", "els", "els_forward", "semantic_deg", "out_of_range"):
                assert getattr(a, col) == getattr(b, col), col
    n_cct, n_h2h = len(cases["cct"]), len(cases["h2h"])
    assert len(mesh.got) == len(rig.got) == 2 * n_cct + n_h2h  # cct's forward and return legs, h2h's one
    for r in mesh.got:
        for side in (r.source, r.target):
            assert isinstance(side, MeshOnlyRig) and not isinstance(side, Rig)
            for name in ("keypoints", "parents", "weights", "bone_names"):
                with pytest.raises(RigWithheld, match="reads_rig=False"):
                    getattr(side, name)
            full = data.characters[side.character_id].rig
            assert np.array_equal(side.vertices, full.vertices) and np.array_equal(side.faces, full.faces)
            assert not side.vertices.flags.writeable
        assert r.extras == {}  # m_sink is bone-indexed
    for r in rig.got:  # a rig-reading method still gets every bone
        assert isinstance(r.target, Rig) and len(r.target.keypoints) == len(r.target.bone_names) > 0
    # the return leg starts from the forward answer: the posed source of cct's second requests
    returned = [r for r in mesh.got if r.case_id in {c.case_id for c in cases["cct"]}][n_cct:2 * n_cct]
    for r, c in zip(returned, cases["cct"]):
        assert r.target.character_id == c.source_id and r.source.character_id == c.target_id
        assert np.allclose(r.source_posed, data.characters[c.target_id].rig.vertices + 0.01)


def test_a_mesh_only_method_that_reads_the_rig_fails_saying_so(bench):
    cases, data = bench
    rows = evaluate_batch(ClaimsMeshOnlyReadsBones(), "cct", cases["cct"], data)
    assert all(r.status == "failed" and "RigWithheld" in r.error and "reads_rig=False" in r.error for r in rows)


def _tiny_rig():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    w = SparseWeights(np.array([[0], [0], [1]], np.int32), np.ones((3, 1), np.float32), 2)
    return Rig("t/a", "humanoid", v, np.array([[0, 1, 2]], np.int32), np.zeros((2, 3), np.float32),
               np.array([-1, 0], np.int32), w, ("root", "arm"))


def test_motion_requests_keep_their_rig_and_metadata_is_checked():
    rig = _tiny_rig()
    motion = MotionRequest(rig, np.zeros((2, 2, 7), np.float32), np.array([True, False]), 30.0)
    assert mesh_only(motion) is motion  # the motion is stated on the bones: nothing to strip
    stripped = mesh_only(TransferRequest(rig, rig.vertices, rig, "x", {"m_sink": np.eye(2)}))
    assert isinstance(stripped.target, MeshOnlyRig) and stripped.extras == {}
    assert stripped.target.height == pytest.approx(rig.height) and stripped.target.size == pytest.approx(rig.size)
    assert MethodMetadata(name="m", version="1").reads_rig is True  # the default: safe for any plug-in
    with pytest.raises(ValueError, match="reads_rig"):
        MethodMetadata(name="m", version="1", reads_rig="no")


@pytest.mark.slow
def test_bundled_mesh_only_methods_answer_without_the_rig(bench):
    """Every registered method that declares meshes only answers stripped cct requests (both legs)."""
    from mimicbench.benchmark.registry import METHODS, get_method

    cases, data = bench
    declared = []
    for name in METHODS.names():
        try:
            method = get_method(name)
        except Exception:  # a plug-in that cannot load is another test's business
            continue
        if method.metadata.reads_rig or "cct" not in method.metadata.protocols:
            continue
        declared.append(name)
        for r in evaluate_batch(method, "cct", cases["cct"][:1], data):
            assert r.status == "ok", f"{name}: {r.error}"
    assert {"identity", "npt", "cgt", "sfpt"} <= set(declared)
