"""The apparel protocol (benchmark/protocols/apparel.py) and its baselines, checked by hand."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mimicbench.baselines.body_only import BodyOnly
from mimicbench.baselines.lbs_kinematic import LbsKinematic
from mimicbench.benchmark.batch import evaluate_batch
from mimicbench.benchmark.normalisation import RestFrame
from mimicbench.benchmark.protocols import get_protocol
from mimicbench.benchmark.protocols.apparel import BURN_IN, apparel_scores, burn_in_frames
from mimicbench.benchmark.protocols.base import CasePool, EvalData
from mimicbench.benchmark.registry import get_method
from mimicbench.datagen.apparel.stage import simulate_dataset
from mimicbench.geometry.mesh import unique_edges
from mimicbench.schemas.shards import write_records
from tests.apparel_toys import make_character, make_motion, quick_turn

SHIFT = 0.01  # metres: the hand-made "simulation" moves every apparel bone by this along +X


def _hand_case(tmp_path):
    """A toy dataset whose simulated clip is the kinematic one with apparel bones shifted by SHIFT."""
    c = make_character("toy/a")
    kin = make_motion(c, quick_turn(20, 4), "turn")
    sim_t = kin.transforms.copy()
    sim_t[:, 1:, 4] += SHIFT
    sim = dataclasses.replace(kin, motion_id=kin.motion_id + "@sim", name="turn@sim", transforms=sim_t)
    root = tmp_path / "hand"
    write_records(root, "characters", [c], split="train")
    write_records(root, "motions", [kin, sim], split="train")
    return root, c


def test_scores_by_hand_and_lbs_kinematic_on_a_hand_case(tmp_path):
    root, c = _hand_case(tmp_path)
    proto = get_protocol("apparel")
    cases = proto.build_cases(CasePool.load(root, "all"), None, 3, seed=0)
    assert len(cases) == 3 and all(k.protocol == "apparel" and k.source_id == k.target_id == "toy/a" for k in cases)
    k = len(c.parents)
    for case in cases:
        assert case.motion_id == "toy/a/turn" and case.case_id.startswith("apparel/toy/a->toy/a/turn#")
        # the request starts at the clip's first frame (the window starts within BURN_IN of it)
        assert case.source_transforms.shape == ((case.frame + 16) * k, 7) and case.target_transforms.shape == (16 * k, 7)
    rows = {r.case_id: r for r in evaluate_batch(get_method("lbs_kinematic"), proto, cases, EvalData.load(root))}
    height = float(np.ptp(c.vertices[:, 1]))
    share = c.apparel_vertex_mask.mean()
    for r in rows.values():
        assert r.status == "ok", r.error
        # by hand: body vertices exact; every apparel vertex off by SHIFT (one-hot weights, pure translation)
        assert r.pmd_body == pytest.approx(0.0, abs=1e-9) and r.pmd_body_cm == pytest.approx(0.0, abs=1e-9)
        assert r.pmd_apparel == pytest.approx(SHIFT / height * 100, rel=1e-4)
        assert r.pmd == pytest.approx(share * SHIFT / height * 100, rel=1e-4)
        assert r.pmd_apparel_cm == pytest.approx(SHIFT / height * 170, rel=1e-4)
        assert r.els == pytest.approx(1.0, abs=1e-6)  # the toy's parts are separate: no edge is stretched
        assert len(r.pmd_frames) == 16 and np.allclose(r.pmd_apparel_frames, r.pmd_apparel)
    # a method that does not list the protocol gets not_supported rows, not failures
    assert {r.status for r in evaluate_batch(get_method("identity"), proto, cases, EvalData.load(root))} == \
        {"not_supported"}


def _long_hand_case(frames: int):
    """A hand case's character and its (kinematic, simulated) clip of ``frames`` frames, in memory."""
    c = make_character("toy/a")
    kin = make_motion(c, np.linspace(0.0, np.pi, frames), "spin")
    sim_t = kin.transforms.copy()
    sim_t[:, 1:, 4] += SHIFT
    return c, kin, dataclasses.replace(kin, motion_id=kin.motion_id + "@sim", name="spin@sim", transforms=sim_t)


def test_a_request_starts_at_the_clip_start_or_burn_in_before_the_window():
    """Case rows by hand: kinematic frames from max(0, start - BURN_IN) to the window's end, simulated
    frames of the window only."""
    c, kin, sim = _long_hand_case(130)
    proto, k = get_protocol("apparel"), len(c.parents)
    assert BURN_IN == 90
    for start, first in ((0, 0), (7, 0), (90, 0), (100, 10), (114, 24)):
        case = proto.make_case(c, c, (kin, sim), start)
        assert case.frame == start
        np.testing.assert_array_equal(case.source_transforms.reshape(-1, k, 7), kin.transforms[first:start + 16])
        np.testing.assert_array_equal(case.target_transforms.reshape(-1, k, 7), sim.transforms[start:start + 16])
        assert burn_in_frames(case, k) == start - first
    with pytest.raises(ValueError, match="B>=0"):  # more simulated than kinematic frames: refused
        burn_in_frames(dataclasses.replace(case, source_transforms=case.source_transforms[: 8 * k]), k)


class _RightInTheWindowOnly(LbsKinematic):
    """The hand case's truth in the last WINDOW frames (LBS, apparel vertices + SHIFT in x) and 1 m off
    everywhere in the burn-in frames before them."""

    def __init__(self, apparel):
        self.apparel = apparel
        self.frames = []

    def transfer_motion(self, requests):
        out = []
        for r, pred in zip(requests, super().transfer_motion(requests)):
            self.frames.append(len(pred))
            pred = pred.copy()
            pred[-16:, self.apparel, 0] += SHIFT
            pred[:-16] += 1.0
            out.append(pred)
        return out


def test_only_the_window_is_scored(tmp_path):
    c, kin, sim = _long_hand_case(130)
    root = tmp_path / "long"
    write_records(root, "characters", [c], split="train")
    write_records(root, "motions", [kin, sim], split="train")
    proto = get_protocol("apparel")
    cases = [proto.make_case(c, c, (kin, sim), f) for f in (0, 40, 100, 114)]
    method = _RightInTheWindowOnly(np.asarray(c.apparel_vertex_mask, bool))
    rows = evaluate_batch(method, proto, cases, EvalData.load(root))
    assert sorted(method.frames) == [16, 56, 106, 106]  # every request: burn-in + window frames
    for r in rows:
        assert r.status == "ok", r.error
        assert len(r.pmd_frames) == 16
        for key in ("pmd", "pmd_apparel", "pmd_body"):
            assert getattr(r, key) == pytest.approx(0.0, abs=1e-4)
        assert r.els == pytest.approx(1.0, abs=1e-5)
    # lbs_kinematic on the same cases: the apparel off by SHIFT in the window, as on the short clip
    height = float(np.ptp(c.vertices[:, 1]))
    for r in evaluate_batch(get_method("lbs_kinematic"), proto, cases, EvalData.load(root)):
        assert r.pmd_apparel == pytest.approx(SHIFT / height * 100, rel=1e-4)


def test_apparel_scores_per_frame_by_hand():
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [1, 2, 0]], np.float64)  # height 2
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    frame = RestFrame.of(rest, unique_edges(faces))
    truth = np.stack([rest, rest])
    pred = truth.copy()
    pred[0, 3] += [0.2, 0, 0]  # frame 0: apparel vertex 3 off by 0.2
    pred[1, 0] += [0, 0.4, 0]  # frame 1: body vertex 0 off by 0.4
    s = apparel_scores(pred, truth, np.array([False, False, False, True]), frame)
    assert s["pmd_apparel_frames"] == pytest.approx([10.0, 0.0])  # 0.2 / 2 x100
    assert s["pmd_body_frames"] == pytest.approx([0.0, 0.4 / 3 / 2 * 100])
    assert s["pmd_frames"] == pytest.approx([0.2 / 4 / 2 * 100, 0.4 / 4 / 2 * 100])
    assert s["pmd_apparel"] == pytest.approx(5.0) and s["pmd_apparel_cm"] == pytest.approx(5.0 * 1.7)
    # ELS of frame 0 from the five edges' lengths
    e = unique_edges(faces)
    lengths = lambda v: np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)  # noqa: E731
    assert s["els_frames"][0] == pytest.approx(1 - np.mean(np.abs(lengths(pred[0]) / lengths(rest) - 1)))


def test_baselines_on_simulated_toy_data(tmp_path):
    root = tmp_path / "toy"
    c = make_character("toy/a")
    write_records(root, "characters", [c], split="train")
    write_records(root, "motions", [make_motion(c, quick_turn(24, 4), "turn")], split="train")
    out = tmp_path / "sim"
    simulate_dataset(root, out, relax=4, progress=False)
    proto = get_protocol("apparel")
    cases = proto.build_cases(CasePool.load(out, "all"), None, 2, seed=0)
    data = EvalData.load(out)
    assert data.motion_fps["toy/a/turn"] == pytest.approx(30.0)
    lbs = {r.case_id: r for r in evaluate_batch(LbsKinematic(), proto, cases, data)}
    body = {r.case_id: r for r in evaluate_batch(BodyOnly(), proto, cases, data)}
    for cid in lbs:
        assert lbs[cid].status == body[cid].status == "ok"
        assert lbs[cid].pmd_body == pytest.approx(0.0, abs=1e-9) and body[cid].pmd_body == pytest.approx(0.0, abs=1e-9)  # body bones untouched by every route
        assert lbs[cid].pmd_apparel > 0.1 and body[cid].pmd_apparel > 0.1  # neither lags like the simulation
    # body_only: the chain moves rigidly with the torso (its only body bone), by hand
    req_t = cases[0].source_transforms.reshape(-1, len(c.parents), 7)
    pred = BodyOnly().transfer_motion([_request(c, req_t)])[0]
    apparel = c.apparel_vertex_mask
    for f in range(len(req_t)):
        w, x, y, z = req_t[f, 0, :4]
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        expect = (c.vertices[apparel] - c.keypoints[0]) @ rot.T + req_t[f, 0, 4:]
        np.testing.assert_allclose(pred[f][apparel], expect, atol=1e-5)


def _request(c, transforms):
    from mimicbench.benchmark.request import MotionRequest
    from mimicbench.benchmark.rigs import CharacterData

    return MotionRequest(CharacterData(c).rig, transforms, ~c.apparel_bone_mask, 30.0)


def test_wrong_shapes_fail_the_case(tmp_path):
    root, _ = _hand_case(tmp_path)
    proto = get_protocol("apparel")
    cases = proto.build_cases(CasePool.load(root, "all"), None, 1, seed=0)

    class OneFrame(LbsKinematic):
        def transfer_motion(self, requests):
            return [p[0] for p in super().transfer_motion(requests)]

    rows = evaluate_batch(OneFrame(), proto, cases, EvalData.load(root))
    assert rows[0].status == "failed" and "wrong shape" in rows[0].error


def test_leaderboard_strips_show_the_window_middle_frame(tmp_path):
    """The leaderboard's strips for apparel cases: a window's middle frame, the frame the samples keep.
    By hand: the truth panel is the prediction panel of lbs_kinematic with apparel vertices + SHIFT in x."""
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.benchmark.cases import write_cases
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.leaderboard_strips import build_strips
    from mimicbench.datagen.render.panel import Panel

    root, c = _hand_case(tmp_path)
    cases = get_protocol("apparel").build_cases(CasePool.load(root, "all"), None, 2, seed=0)
    write_cases(root, {"apparel": cases}, {"protocols": ["apparel"]})
    res = tmp_path / "res"
    run_benchmark(root, ["lbs_kinematic"], ("apparel",), res, progress=False, in_process=True)
    strips, note = build_strips(res, aggregate(res))
    assert note is None and strips and all(s.protocol == "apparel" for s in strips)
    for s in strips:
        assert "middle frame" in s.title
        source, truth, pred = [p for p in s.items if isinstance(p, Panel)]
        apparel = c.apparel_vertex_mask
        np.testing.assert_allclose(truth.vertices[~apparel], pred.vertices[~apparel], atol=1e-5)
        np.testing.assert_allclose(truth.vertices[apparel] - pred.vertices[apparel],
                                   np.tile([SHIFT, 0, 0], (apparel.sum(), 1)), atol=1e-5)
        np.testing.assert_allclose(source.vertices, pred.vertices, atol=1e-5)  # kinematic source = lbs_kinematic


def test_pose_protocols_draw_kinematic_clips_only(tmp_path):
    """h2h draws poses from ``turn``, never from its simulated twin ``turn@sim`` (same body pose)."""
    a, b = (dataclasses.replace(make_character(i), skeleton_id="skel-toy") for i in ("toy/a", "toy/b"))
    motions = []
    for c in (a, b):
        kin = make_motion(c, quick_turn(20, 4), "turn")
        motions += [kin, dataclasses.replace(kin, motion_id=kin.motion_id + "@sim", name="turn@sim")]
    root = tmp_path / "twins"
    write_records(root, "characters", [a, b], split="train")
    write_records(root, "motions", motions, split="train")
    pool = CasePool.load(root, "all")
    assert sorted(m.name for m in pool.motions["toy/a"]) == ["turn", "turn@sim"]
    draws = pool.frames_for(np.random.default_rng(0), "toy/a", 100)
    assert len(draws) == 19 and {m.name for m, _ in draws} == {"turn"}  # every frame but the rest frame, once
    cases = get_protocol("h2h").build_cases(pool, None, 50, seed=0)
    assert len(cases) == 2 * 19 and {k.motion_id.rsplit("/", 1)[1] for k in cases} == {"turn"}


def test_strips_show_the_window_middle_frame_after_a_burn_in(tmp_path):
    """With burn-in frames in the request, the source panel is still the window's middle frame: the
    kinematic pose at frame + 8 (by hand: LBS of the clip's frame, one-hot weights), the prediction's frame."""
    from mimicbench.benchmark.aggregate import aggregate
    from mimicbench.benchmark.cases import write_cases
    from mimicbench.benchmark.evaluator import run_benchmark
    from mimicbench.benchmark.leaderboard_strips import build_strips
    from mimicbench.datagen.render.panel import Panel
    from mimicbench.geometry.skinning import linear_blend_skinning

    c, kin, sim = _long_hand_case(130)
    root = tmp_path / "long"
    write_records(root, "characters", [c], split="train")
    write_records(root, "motions", [kin, sim], split="train")
    proto = get_protocol("apparel")
    cases = [proto.make_case(c, c, (kin, sim), f) for f in (40, 100)]
    write_cases(root, {"apparel": cases}, {"protocols": ["apparel"]})
    res = tmp_path / "res"
    run_benchmark(root, ["lbs_kinematic"], ("apparel",), res, progress=False, in_process=True)
    strips, note = build_strips(res, aggregate(res))
    assert note is None and {s.case_id for s in strips} == {k.case_id for k in cases}
    frame = {k.case_id: k.frame for k in cases}
    for s in strips:
        source, truth, pred = [p for p in s.items if isinstance(p, Panel)]
        expect = linear_blend_skinning(c.vertices, c.keypoints, c.weights, kin.transforms[frame[s.case_id] + 8])
        np.testing.assert_allclose(source.vertices, expect, atol=1e-5)
        np.testing.assert_allclose(pred.vertices, expect, atol=1e-5)
