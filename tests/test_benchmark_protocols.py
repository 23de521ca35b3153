"""Protocols as modules: registry, dispatch without protocol names in the evaluator, methods
that do not support a protocol, and same-skeleton ground truth end to end."""
import numpy as np
import pytest

from mimicbench.benchmark.cases import build_cases, write_cases
from mimicbench.benchmark.evaluator import run_benchmark
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.benchmark.protocols import available_protocols, get_protocol, register_protocol
from mimicbench.benchmark.protocols.base import BenchmarkProtocol, Outcome
from mimicbench.benchmark.registry import register
from mimicbench.benchmark.results import method_dir, read_result_records
from mimicbench.baselines.name_copy import NameCopy
from mimicbench.benchmark.scoring import score_pose
from mimicbench.schemas.case import CaseRecord
from tests.family_fixtures import add_family


class ScaledSourceCopy(PoseTransferMethod):
    """The posed source scaled by the size ratio: the exact answer when the target is a copy of
    the source scaled about the origin. Counts the requests it is given."""

    metadata = MethodMetadata(name="scaled_copy", version="1", licence="MIT", protocols=("h2h", "toy"))
    calls = 0

    def transfer(self, requests):
        ScaledSourceCopy.calls += len(requests)
        return [np.asarray(r.source_posed) * np.float32(r.target.size / r.source.size) for r in requests]


class ToyProtocol(BenchmarkProtocol):
    """Each animated character to itself, ground truth = the source pose (scored by extent)."""

    name = "toy"
    title = "self transfer"
    headline = "extent"

    def candidate_pairs(self, pool):
        return [(a, a) for a in pool.characters]

    def make_case(self, source, target, motion, frame):
        t = motion.transforms[frame]
        return CaseRecord(self.case_id(source, target, motion, frame), self.name, source.character_id,
                          target.character_id, motion.motion_id, frame, t, t, source.category, target.category)

    def evaluate(self, cases, data, call):
        chars = [data.characters[c.source_id] for c in cases]
        posed = [data.posed(ch, c.source_transforms) for ch, c in zip(chars, cases)]
        answers = call([data.request(ch, p, ch, c.case_id) for ch, p, c in zip(chars, posed, cases)])
        return [Outcome(c, "failed", err, sec) if err else
                Outcome(c, "ok", None, sec, score_pose(pred, p, data.frame(ch), self.headline))
                for c, ch, p, (pred, err, sec) in zip(cases, chars, posed, answers)]


def test_registry_knows_the_builtin_protocols_and_suggests_names():
    assert available_protocols()[:3] == ["h2h", "h2h_xskel", "cct"]
    assert get_protocol("h2h").headline == "height" and get_protocol("cct").headline == "extent"
    with pytest.raises(ValueError, match="Did you mean 'cct'"):
        get_protocol("ctt")


def test_method_metadata_protocols():
    assert MethodMetadata("m", "1").protocols == ("h2h", "cct")
    assert MethodMetadata("m", "1", protocols=["h2h"]).protocols == ("h2h",)
    with pytest.raises(ValueError, match="non-empty tuple of protocol names"):
        MethodMetadata("m", "1", protocols=())


def test_a_new_protocol_runs_through_the_evaluator_and_unsupported_methods_are_not_called(small_zoo, tmp_path):
    import shutil

    register_protocol("toy", ToyProtocol)
    data = tmp_path / "d"
    shutil.copytree(small_zoo, data)
    cases = build_cases(data, "test", protocols=("toy",), sizes={"toy": (3, 2)})
    assert len(cases["toy"]) == 6
    write_cases(data, cases, {"test": True})
    register("scaled_copy", ScaledSourceCopy)
    summary = run_benchmark(data, ["scaled_copy", "identity"], ["toy"], tmp_path / "res", progress=False)
    assert summary["not_supported"] == 6 and summary["failed"] == 0
    rows = read_result_records(method_dir(tmp_path / "res", "scaled_copy", "1"))
    assert len(rows) == 6 and all(r.status == "ok" and r.pmd < 1e-4 and r.pmd_aligned < 1e-4 for r in rows)
    ident = read_result_records(method_dir(tmp_path / "res", "identity", "1"))
    assert {r.status for r in ident} == {"not_supported"} and all(r.pmd is None for r in ident)
    assert "does not support the toy protocol" in ident[0].error


def test_same_skeleton_copy_with_translated_bones_scores_zero(small_zoo, tmp_path):
    copies = {"zoo/twin": 1.0, "zoo/big": 1.5}
    data, base, _ = add_family(small_zoo, tmp_path / "d", "quadruped", copies)
    cases = build_cases(data, "all", h2h_pairs=None, h2h_poses=6, cct_pairs=2, cct_poses=1)
    ours = [c for c in cases["h2h"] if c.source_id == base]
    assert {c.target_id for c in ours} == set(copies) and any(c.motion_id.endswith("-ik") for c in ours)
    write_cases(data, cases, {"test": True})
    register("scaled_copy", ScaledSourceCopy)
    ScaledSourceCopy.calls = 0
    summary = run_benchmark(data, ["scaled_copy", "name_copy"], ["h2h", "cct"], tmp_path / "res", progress=False,
                            in_process=True)  # calls are counted in this process
    assert ScaledSourceCopy.calls == len(cases["h2h"])  # never called on cct
    assert summary["not_supported"] == len(cases["cct"])
    rows = {r.case_id: r for r in read_result_records(method_dir(tmp_path / "res", "scaled_copy", "1"))}
    for c in ours:
        r = rows[c.case_id]
        assert r.status == "ok", r.error
        for m in ("pmd", "pmd_height", "pmd_extent", "pmd_aligned", "pmd_squared"):
            assert getattr(r, m) < 2e-3, (c.case_id, m, getattr(r, m))
        assert abs(r.els - 1) < 1e-4
    assert all(rows[c.case_id].status == "not_supported" for c in cases["cct"])
    # name_copy reads translations off the posed vertices too: near exact on the clip that moves bones
    copied = {r.case_id: r for r in read_result_records(method_dir(tmp_path / "res", "name_copy", NameCopy.metadata.version))}
    ik = [copied[c.case_id].pmd for c in ours if c.motion_id.endswith("-ik")]
    assert ik and max(ik) < 1.0, ik
