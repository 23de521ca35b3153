"""The validity probes and the role match on small labelled rigs, by hand: the mirror moves the
other side, the fore/hind swap drives the legs by the arms, the frozen limb stays at rest, and the
uncorrupted role transfer reproduces the source's pose on its own rig."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.baselines.probes import corruptions
from mimicbench.baselines.probes.methods import (NearestJointMirrored, ProbeForeHind, ProbeFrozenLimb, ProbeHalfAngle,
                                      ProbeMirror, ProbeNoise15, ProbeRest, ProbeRoleTransfer)
from mimicbench.benchmark.request import TransferRequest
from mimicbench.benchmark.role_match import bone_mass, match_by_role
from mimicbench.benchmark.semantic import character_role_classes
from tests.role_rigs import pose, quadruped, t_pose_humanoid


def request(src, posed, tgt, case_id="probe/a->b/clip#1"):
    roles = {"source_roles": src.record.bone_roles, "source_classes": character_role_classes(src.record),
             "target_roles": tgt.record.bone_roles, "target_classes": character_role_classes(tgt.record)}
    return TransferRequest(src.rig, posed, tgt.rig, case_id, {"hidden_roles": roles})


def bone_displacement(char, posed, bone):
    owner = char.rig.weights.indices[:, 0]
    return float(np.abs(posed[owner == char.names.index(bone)] - char.rig.vertices[owner == char.names.index(bone)]).max())


def test_class_maps_by_hand():
    assert corruptions.swap_sides("left/forelimb") == "right/forelimb"
    assert corruptions.swap_sides("right/hindlimb") == "left/hindlimb"
    assert corruptions.swap_sides("tail") == "tail"
    assert corruptions.swap_fore_hind("left/forelimb") == "left/hindlimb"
    assert corruptions.swap_fore_hind("hindlimb") == "forelimb"
    assert corruptions.swap_fore_hind("head") == "head"


def test_role_match_exact_roles_then_class_and_depth():
    a, b = t_pose_humanoid(), t_pose_humanoid("b", extra_spine=True)
    ca, cb = character_role_classes(a.record), character_role_classes(b.record)
    m = match_by_role(a.record.bone_roles, ca, a.rig.parents, bone_mass(a.rig), b.record.bone_roles, cb, b.rig.parents,
                      bone_mass(b.rig))
    for bone in ("l_arm", "r_fore", "head", "l_shin"):
        assert a.names[m[b.names.index(bone)]] == bone
    assert a.names[m[b.names.index("chest")]] == "spine"  # spine/2: no such role in a; same class, nearest mass position
    mirrored = match_by_role(a.record.bone_roles, ca, a.rig.parents, bone_mass(a.rig), b.record.bone_roles, cb,
                             b.rig.parents, bone_mass(b.rig), class_map=corruptions.swap_sides)
    assert a.names[mirrored[b.names.index("l_arm")]] == "r_arm"
    assert a.names[mirrored[b.names.index("r_shin")]] == "l_shin"


def test_role_transfer_reproduces_the_pose_on_the_same_rig():
    h = t_pose_humanoid()
    _, posed = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -60), h.names.index("r_thigh"): ((1, 0, 0), -30)})
    out = ProbeRoleTransfer().transfer([request(h, posed, h)])[0]
    np.testing.assert_allclose(out, posed, atol=2e-4)


def test_mirror_moves_the_other_side():
    h = t_pose_humanoid()
    _, posed = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -60)})
    out = ProbeMirror().transfer([request(h, posed, h)])[0]
    assert bone_displacement(h, out, "l_arm") < 1e-4
    assert bone_displacement(h, out, "r_arm") > 0.1
    # the reflected motion: the right arm swings forward (+z) as the left one did
    owner = h.rig.weights.indices[:, 0]
    assert out[owner == h.names.index("r_fore"), 2].mean() > 0.3


def test_fore_hind_swap_drives_the_legs_by_the_arms():
    h, d = t_pose_humanoid(), quadruped()
    _, posed = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -60)})
    right = ProbeRoleTransfer().transfer([request(h, posed, d)])[0]
    swapped = ProbeForeHind().transfer([request(h, posed, d)])[0]
    assert bone_displacement(d, right, "l_front") > 0.1 and bone_displacement(d, right, "l_hind") < 1e-4
    assert bone_displacement(d, swapped, "l_hind") > 0.1 and bone_displacement(d, swapped, "l_front") < 1e-4


def test_frozen_limb_half_angle_noise_and_rest():
    h = t_pose_humanoid()
    _, posed = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -60)})
    r = request(h, posed, h)
    assert bone_displacement(h, ProbeFrozenLimb().transfer([r])[0], "l_arm") < 1e-4
    half = ProbeHalfAngle().transfer([r])[0]
    _, expected = pose(h.rig, {h.names.index("l_arm"): ((0, 1, 0), -30)})
    np.testing.assert_allclose(half, expected, atol=2e-4)
    noisy, again = ProbeNoise15().transfer([r])[0], ProbeNoise15().transfer([r])[0]
    np.testing.assert_array_equal(noisy, again)  # seeded by the case
    assert np.abs(noisy - posed).max() > 0.01
    np.testing.assert_array_equal(ProbeRest().transfer([r])[0], h.rig.vertices)


def test_probes_refuse_a_request_without_hidden_roles():
    h = t_pose_humanoid()
    with pytest.raises(ValueError, match="hidden role labels"):
        ProbeRoleTransfer().transfer([TransferRequest(h.rig, h.rig.vertices, h.rig, "x")])


def test_nearest_joint_mirrored_matches_across_sides():
    h = t_pose_humanoid()
    pairs = NearestJointMirrored.pairs(h.rig, h.rig)
    match = dict((int(t), int(s)) for s, t in pairs)
    assert h.names[match[h.names.index("l_arm")]] == "r_arm"
    assert h.names[match[h.names.index("head")]] == "head"


def test_class_mass_position_by_hand():
    from mimicbench.benchmark.role_match import class_mass_position

    # one class of three depths (masses 1, 4, 5) under an unlabelled root
    classes = [None, "left/forelimb", "left/forelimb", "left/forelimb"]
    pos = class_mass_position(classes, np.array([-1, 0, 1, 2]), np.array([9.0, 1.0, 4.0, 5.0]))
    assert np.isnan(pos[0])
    np.testing.assert_allclose(pos[1:], [0.05, 0.3, 0.75])
