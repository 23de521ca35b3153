"""The apparel protocol's acceleration error and penetration share, by hand on toy sequences,
and the jitter probe they must detect."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.baselines.mmdmc.probe_jitter import apparel_vertices, jitter
from mimicbench.benchmark.apparel_metrics import (accel_error, clear_at_rest, contact_reach, penetration_share,
                                       second_differences)
from mimicbench.datagen.apparel.body_shapes import BodyPiece

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])


def test_second_differences_of_a_parabola_are_its_acceleration():
    fps = 30.0
    t = np.arange(6) / fps
    x = np.zeros((6, 1, 3))
    x[:, 0, 1] = 0.5 * -9.8 * t ** 2  # a falling point: every second difference is -9.8 m/s^2
    np.testing.assert_allclose(second_differences(x, fps)[:, 0], [[0.0, -9.8, 0.0]] * 4, atol=1e-9)


def test_accel_error_by_hand():
    fps, f = 10.0, 5
    pred = np.zeros((f, 3, 3))
    truth = np.zeros((f, 3, 3))
    pred[:, 0, 0] = [0.0, 0.0, 0.01, 0.0, 0.0]  # second differences x100: 1, -2, 1 m/s^2
    truth[:, 1, 2] = 0.5 * 3.0 * (np.arange(f) / fps) ** 2  # constant 3 m/s^2 along z; pred stays still
    pred[:, 2, :] = np.arange(f)[:, None] * 0.5  # uniform motion: no acceleration, and not apparel anyway
    apparel = np.array([True, True, False])
    # vertex 0: |1|, |-2|, |1|; vertex 1: 3, 3, 3 -> mean over 6 values
    expected = (1 + 2 + 1 + 3 + 3 + 3) / 6
    assert accel_error(pred, truth, apparel, fps, 1.70) == pytest.approx(expected)
    # a character half as tall is scaled up twice to 1.70 m
    assert accel_error(pred, truth, apparel, fps, 0.85) == pytest.approx(2 * expected)
    assert accel_error(pred[:2], truth[:2], apparel, fps, 1.70) is None  # no second difference
    assert accel_error(pred, truth, np.zeros(3, bool), fps, 1.70) is None
    with pytest.raises(ValueError, match="one shape"):
        accel_error(pred, truth[:, :2], apparel, fps, 1.70)


def box_piece(half: float = 0.1) -> BodyPiece:
    """An axis-aligned box of half side ``half`` round bone 0's head (at the origin), planes by hand."""
    corners = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)])
    planes = np.array([[1, 0, 0, -half], [-1, 0, 0, -half], [0, 1, 0, -half], [0, -1, 0, -half],
                       [0, 0, 1, -half], [0, 0, -1, -half]], np.float64)
    return BodyPiece(0, corners, planes, np.zeros(3), float(np.sqrt(3) * half))


def test_penetration_share_of_points_inside_near_and_clear_of_a_box():
    piece = box_piece()
    # inside, 0.5 mm outside, 2 mm outside, far away
    points = np.array([[0.0, 0.0, 0.0], [0.1005, 0.0, 0.0], [0.0, 0.102, 0.0], [0.5, 0.0, 0.0]])
    poses = np.tile(IDENTITY, (2, 1, 1))  # two frames, one bone
    counted = np.ones(4, bool)
    reach = contact_reach(1.70)
    assert reach == pytest.approx(0.001)
    assert penetration_share(np.stack([points, points]), [piece], poses, counted, reach) == pytest.approx(50.0)
    # a character 3.4 m tall: 2 mm; 2.5 mm out is still clear of it
    far = points.copy()
    far[2, 1] = 0.1025
    assert penetration_share(far[None], [piece], poses[:1], counted, contact_reach(3.4)) == pytest.approx(50.0)
    closer = points.copy()
    closer[2, 1] = 0.1015  # 1.5 mm out: within 2 mm
    assert penetration_share(closer[None], [piece], poses[:1], counted, contact_reach(3.4)) == pytest.approx(75.0)
    # the second frame moves the box 1 m away (bone 0 translated): nothing near it there
    moved = poses.copy()
    moved[1, 0, 4] = 1.0
    assert penetration_share(np.stack([points, points]), [piece], moved, counted, reach) == pytest.approx(25.0)
    # only counted points are scored
    assert penetration_share(points[None], [piece], poses[:1], np.array([False, False, True, True]),
                             reach) == pytest.approx(0.0)
    assert penetration_share(points[None], [piece], poses[:1], np.zeros(4, bool), reach) is None


def test_points_already_touching_at_rest_are_not_counted():
    piece = box_piece()
    rest = np.array([[0.0, 0.05, 0.0], [0.1005, 0.0, 0.0], [0.102, 0.0, 0.0], [0.0, 0.3, 0.0]])
    keypoints = np.zeros((1, 3))  # bone 0's head at the origin: the rest pose is the identity
    np.testing.assert_array_equal(clear_at_rest([piece], keypoints, rest, 0.001), [False, False, True, True])


def test_jitter_probe_moves_only_apparel_and_its_second_differences_match_the_noise():
    f, n = 400, 6
    posed = np.zeros((f, n, 3), np.float32)
    weights = np.zeros((n, 2))
    weights[:3, 0] = 1.0  # body bone 0
    weights[3:, 1] = 1.0  # apparel bone 1
    mask = apparel_vertices(weights, np.array([True, False]))
    np.testing.assert_array_equal(mask, [False] * 3 + [True] * 3)
    sigma = 0.001
    out = jitter(posed, mask, sigma, seed=7)
    np.testing.assert_array_equal(out[:, :3], 0.0)
    np.testing.assert_array_equal(out, jitter(posed, mask, sigma, seed=7))  # seeded
    a = second_differences(out[:, 3:], 30.0)
    # independent noise: each axis' second difference has std sqrt(6) sigma fps^2 (1 + 4 + 1 = 6)
    assert np.std(a) == pytest.approx(np.sqrt(6) * sigma * 900, rel=0.05)


def test_protocol_rows_carry_both_scores_and_see_the_jitter_probe(tmp_path):
    # the hand case of tests/test_apparel_protocol.py: the "simulation" shifts every apparel bone by a
    # constant 1 cm, so lbs_kinematic has the ground truth's accelerations (accel_error 0); the probe's
    # 1 mm (at 1.70 m) of independent noise per axis gives second differences of mean magnitude
    # sqrt(6) sigma fps^2 sqrt(8 / pi) (a 3D normal's mean length is sqrt(8 / pi) times its std),
    # while its PMD_a moves by about sigma^2 / (2 shift), a small share of the shift
    from mimicbench.benchmark.batch import evaluate_batch
    from mimicbench.benchmark.protocols import get_protocol
    from mimicbench.benchmark.protocols.base import CasePool, EvalData
    from mimicbench.benchmark.registry import get_method
    from tests.test_apparel_protocol import _hand_case

    root, c = _hand_case(tmp_path)
    proto = get_protocol("apparel")
    cases = proto.build_cases(CasePool.load(root, "all"), None, 3, seed=0)
    data = EvalData.load(root)
    lbs = {r.case_id: r for r in evaluate_batch(get_method("lbs_kinematic"), proto, cases, data)}
    probe = {r.case_id: r for r in evaluate_batch(get_method("probe_apparel_jitter"), proto, cases, data)}
    fps = data.motion_fps[cases[0].motion_id]
    expected = np.sqrt(6) * 0.001 * fps ** 2 * np.sqrt(8 / np.pi)
    for k, r in lbs.items():
        assert r.status == probe[k].status == "ok"
        assert r.accel_error == pytest.approx(0.0, abs=1e-3)  # float32 meshes: rounding times fps^2
        assert probe[k].accel_error == pytest.approx(expected, rel=0.2)
        assert abs(probe[k].pmd_apparel_cm - r.pmd_apparel_cm) < 0.05 * r.pmd_apparel_cm
        assert 0.0 <= r.penetration_share <= 100.0 and 0.0 <= probe[k].penetration_share <= 100.0
