"""Zoo motions: clips start at rest, random poses stay within limits, transforms match FK."""
import numpy as np
import pytest

from mimicbench.datagen.zoo.build import build_skeleton, clip_list
from mimicbench.datagen.zoo.clips import generator
from mimicbench.datagen.zoo.motions import clip_transforms, random_poses, ramp, rotvec_to_quat
from mimicbench.datagen.zoo.plan import plan_zoo
from mimicbench.geometry.kinematics import array_to_transforms, local_from_global, rest_transforms
from mimicbench.geometry.quaternion import quat_angle, quat_identity

SPECS = {s.category: s for s in plan_zoo(7, seed=1)}


def test_ramp_starts_at_zero_and_reaches_one():
    r = ramp(20, 8)
    assert r[0] == pytest.approx(0.0, abs=1e-12) and r[8:].min() == pytest.approx(1.0, abs=1e-12) and np.all(np.diff(r) >= 0)


def test_rotvec_to_quat_handles_zero_and_angles():
    q = rotvec_to_quat(np.array([[0, 0, 0], [0, 0, np.pi / 2]]))
    assert np.allclose(q[0], quat_identity())
    assert np.isclose(quat_angle(q[1], quat_identity()), np.pi / 2)


@pytest.mark.parametrize("category", sorted(SPECS))
def test_every_clip_starts_at_rest_and_moves(category):
    skel, _ = build_skeleton(SPECS[category])
    for j, name in enumerate(clip_list(category, skel, 4)):
        rv, root = generator(category, name)(skel, np.random.default_rng(j), 30)
        tr = clip_transforms(skel, rv, root)
        assert tr.shape == (30, skel.num_joints, 7) and np.isfinite(tr).all()
        assert np.allclose(tr[0], rest_transforms(skel.heads), atol=1e-6), name
        assert np.abs(tr[15:, :, 4:] - tr[0, :, 4:]).max() > 1e-3, f"{category}/{name} does not move"


def test_random_poses_stay_within_joint_limits():
    skel, _ = build_skeleton(SPECS["quadruped"])
    rv = random_poses(skel, np.random.default_rng(0), 61)
    angles = np.linalg.norm(rv, axis=-1)
    assert np.all(angles <= skel.limits[None] + 1e-9)
    assert np.all(angles[0] == 0)
    tr = clip_transforms(skel, rv, np.zeros((61, 3)), use_ramp=False)
    q, _ = array_to_transforms(tr)
    local = local_from_global(q, skel.parents)
    assert np.all(quat_angle(local, quat_identity()) <= skel.limits[None] + 1e-4)


def test_gait_legs_have_phase_offsets():
    skel, _ = build_skeleton(SPECS["quadruped"])
    rv, _ = generator("quadruped", "walk")(skel, np.random.default_rng(0), 45)
    lf, rh = skel.index("left/front_leg/1"), skel.index("right/hind_leg/1")
    a, b = rv[:, lf, 0], rv[:, rh, 0]
    assert np.corrcoef(a, b)[0, 1] < 0.5  # not in step: a lateral-sequence walk
