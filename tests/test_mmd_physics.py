"""Rigid bodies and joints into the dataset's frame: the mirror of MMD's left-handed frame checked
against rotation matrices built by hand, limits swapped and negated, Gene's physics stored."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.mmd.physics import physics_records
from mimicbench.datagen.mmd.pmx import parse_pmx, read_pmx
from mimicbench.geometry.quaternion import quat_to_matrix
from tests.mmd_fixtures import pmx_bytes

M = np.diag([1.0, 1.0, -1.0])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.fixture(scope="module")
def fixture_physics():
    m = parse_pmx(pmx_bytes(), "fixture.pmx")
    return m, physics_records(m, "fixture", np.arange(len(m.bones)), 0.08)


def test_body_frame_and_units(fixture_physics):
    m, (bodies, _) = fixture_physics
    hair = bodies[1]
    assert (hair.name, hair.shape, hair.mode, hair.collision_group, hair.collision_mask) == ("髪", "capsule", "dynamic", 3, 0xFFFF)
    np.testing.assert_allclose(hair.size, [0.5 * 0.08, 2 * 0.08, 0], rtol=1e-6)
    np.testing.assert_allclose(hair.position, [0.08, 0.64, 0.16], rtol=1e-6)  # (1, 8, -2) units, z mirrored
    # MMD: R = Ry(ry) Rx(rx) Rz(rz) in its left-handed frame; ours must be M R M
    rx, ry, rz = 0.1, 0.2, 0.3
    expected = M @ (_ry(ry) @ _rx(rx) @ _rz(rz)) @ M
    np.testing.assert_allclose(quat_to_matrix(hair.rotation.astype(np.float64)), expected, atol=1e-6)
    assert (hair.mass, hair.linear_damping) == (pytest.approx(2.0), pytest.approx(0.9))


def test_joint_limits_swapped_and_negated(fixture_physics):
    _, (_, joints) = fixture_physics
    j = joints[0]
    assert (j.kind, j.body_a, j.body_b) == ("spring_6dof", 0, 1)
    # file: translation [-1, 1] x [-2, 2] x [-3, 5]; rotation [-0.1, 0.4] x [-0.2, 0.5] x [-0.3, 0.6]
    np.testing.assert_allclose(j.translation_min, np.array([-1, -2, -5]) * 0.08, rtol=1e-6)
    np.testing.assert_allclose(j.translation_max, np.array([1, 2, 3]) * 0.08, rtol=1e-6)
    np.testing.assert_allclose(j.rotation_min, [-0.4, -0.5, -0.3], rtol=1e-6)
    np.testing.assert_allclose(j.rotation_max, [0.1, 0.2, 0.6], rtol=1e-6)
    np.testing.assert_allclose(j.spring_translation, [10, 20, 30])
    # the meaning of a limit survives the mirror: a rotation allowed in the file, mirrored, is
    # allowed in ours (every corner of the file's box, angle by angle about each axis)
    for axis, rot in enumerate((_rx, _ry, _rz)):
        for a in np.linspace([-0.1, -0.2, -0.3][axis], [0.4, 0.5, 0.6][axis], 5):
            mirrored = M @ rot(a) @ M
            b = [np.arctan2(mirrored[2, 1], mirrored[2, 2]), np.arcsin(mirrored[0, 2]), np.arctan2(mirrored[1, 0], mirrored[0, 0])][axis]
            assert j.rotation_min[axis] - 1e-6 <= b <= j.rotation_max[axis] + 1e-6


def test_gene_physics_records(assets_dir):
    m = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    bodies, joints = physics_records(m, "assets/Gene", np.arange(len(m.bones)), 0.08)
    assert len(bodies) == 87 and len(joints) == 92
    assert sorted({b.mode for b in bodies}) == ["dynamic", "dynamic_bone", "static"]
    assert sum(b.mode == "dynamic_bone" for b in bodies) == 53
    for b, rb in zip(bodies, m.rigid_bodies):
        np.testing.assert_allclose(b.position, rb.position * [0.08, 0.08, -0.08], rtol=1e-5, atol=1e-7)
        assert abs(np.linalg.norm(b.rotation) - 1) < 1e-5 and b.collision_mask == rb.mask
    # a lower limit above the upper one means a free axis (Bullet's convention, which some joints
    # of Gene use): the mirror must keep which axes are limited and which are free
    for j, mj in zip(joints, m.joints):
        np.testing.assert_array_equal(j.rotation_min <= j.rotation_max, mj.rotation_min <= mj.rotation_max)
        np.testing.assert_array_equal(j.translation_min <= j.translation_max, mj.translation_min <= mj.translation_max)
