"""Test-time ARAP refinement: invariants with known answers (rest stays rest, a rigid motion of
the whole mesh stays that rigid motion) and a real glTF character."""
from __future__ import annotations

import numpy as np
import pytest

from baselines.mimicat.arap import ArapRefiner
from mimicbench.quaternion import quat_from_axis_angle, quat_to_matrix
from tests.mimicat_toys import bend, posed, tube_rig


def test_rest_and_rigid_motions_are_fixed_points():
    rig = tube_rig("t", 4)
    ref = ArapRefiner(rigid=0.9)
    v = np.asarray(rig.vertices, np.float64)
    np.testing.assert_allclose(ref.refine("t", v, rig.faces, rig.weights.values, v), v, atol=1e-5)
    r = quat_to_matrix(quat_from_axis_angle(np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2]), 0.9))
    moved = v @ r.T + [0.4, -0.1, 2.0]
    np.testing.assert_allclose(ref.refine("t", v, rig.faces, rig.weights.values, moved), moved, atol=1e-4)


def test_handles_hold_and_every_component_gets_one():
    rig = tube_rig("t", 4)
    ref = ArapRefiner(rigid=0.9)
    b = ref.handles(rig.faces, rig.weights.values, len(rig.vertices))
    top = np.asarray(rig.weights.values).max(axis=1)
    assert set(np.flatnonzero(top >= 0.9)) <= set(b)
    # two copies of the tube side by side, all weights blended: one handle per copy
    faces = np.concatenate([rig.faces, rig.faces + len(rig.vertices)])
    blended = np.full((2 * len(rig.vertices), 2), 0.5)
    assert len(ref.handles(faces, blended, 2 * len(rig.vertices))) == 2
    pose = posed(rig, bend(rig, 0.8, 1))
    out = ref.refine("t", rig.vertices, rig.faces, rig.weights.values, pose)
    bb = ref.handles(rig.faces, rig.weights.values, len(rig.vertices))
    np.testing.assert_allclose(out[bb], pose[bb], atol=1e-5)
    assert np.isfinite(out).all()
    with pytest.raises(ValueError, match="rigid"):
        ArapRefiner(rigid=0)
