"""The file physics as MMD's Bullet runs a model's own joints: the range of two joints between the
same bodies (``SimParams.file_duplicate_ranges``), by hand and on a pendulum stopped where the
narrower range ends."""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.apparel.file_physics import FileWorld
from mimicbench.datagen.apparel.file_plan import intersect_bounds, joint_bounds
from mimicbench.datagen.apparel.params import SimParams
from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

PIVOT = np.array([0.0, 1.0, 0.0])
ARM = 0.5  # metres from the pivot to the bob's centre
RADIUS = 0.05  # the bob, a solid sphere of 1 kg
RATE = 240.0


def _limited_pendulum(half_width, reverse_upper=None, reverse_frame=(1, 0, 0, 0)):
    """A static sphere at the pivot and a 1 kg sphere bob hanging ARM below it on a joint whose X range
    is +-``half_width`` (its other axes free), no spring, no damping; with ``reverse_upper``, a second
    joint between the same bodies from the bob to the pivot whose x range is [-``reverse_upper``,
    ``half_width``] (the bob's x relative to the pivot: [-``half_width``, ``reverse_upper``]) on the
    axes of ``reverse_frame`` (w, x, y, z; the identity: the first joint's axes)."""
    z = np.zeros(3, np.float32)

    def body(i, size, pos, mode, group, mask, bone):
        return RigidBodyRecord("toy", i, f"b{i}", "", bone, "sphere", np.float32(size), np.float32(pos),
                               np.float32([1, 0, 0, 0]), 1.0, 0.0, 0.0, 0.0, 0.5, group, mask, mode)

    bob = PIVOT + [0.0, -ARM, 0.0]
    bodies = [body(0, [0.02, 0, 0], PIVOT, "static", 3, 0xFFFF, 0),
              body(1, [RADIUS, 0, 0], bob, "dynamic", 1, 0xFFFF & ~(1 << 3), 1)]
    lower = np.float32([-half_width, 1.0, 1.0])  # y and z: lower above upper, free (Bullet's convention)
    upper = np.float32([half_width, -1.0, -1.0])
    joints = [JointRecord("toy", 0, "j", "", "spring_6dof", 0, 1, np.float32(PIVOT), np.float32([1, 0, 0, 0]), z, z,
                          lower, upper, z, z)]
    if reverse_upper is not None:
        joints.append(JointRecord("toy", 1, "j-", "", "spring_6dof", 1, 0, np.float32(PIVOT), np.float32(reverse_frame),
                                  z, z, np.float32([-reverse_upper, 1.0, 1.0]), np.float32([half_width, -1.0, -1.0]),
                                  z, z))
    return bodies, joints, np.array([PIVOT, bob])


def _swing(half_width, spin, seconds, reverse_upper=None, duplicate_ranges=False, reverse_frame=(1, 0, 0, 0)):
    """The bob's angle about world X (rad, minus the joint's x angle) after each step, gravity off,
    started at rest turning about the joint's x at ``spin`` rad/s."""
    bodies, joints, keypoints = _limited_pendulum(half_width, reverse_upper, reverse_frame)
    rest = rest_transforms(keypoints).astype(np.float64)
    angles = []
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0]), 1.0 / RATE, 30, 0.08, gravity=0.0,
                   apparel=np.array([False, True]), erp=SimParams().file_erp, max_speed=1e6,
                   duplicate_ranges=duplicate_ranges) as world:
        world.reset(rest)
        mb = world.chains[0][2]
        pb = world.pb
        # Bullet's joint frame: X is the MMD joint's z, Y its x, Z its y; a turn about world X is
        # the joint frame's Y, in which the spherical joint's speed is given
        q = pb.getJointStateMultiDof(mb, 0, physicsClientId=world.client)[0]
        pb.resetJointStateMultiDof(mb, 0, q, targetVelocity=[0.0, spin, 0.0], physicsClientId=world.client)
        for _ in range(int(seconds * RATE)):
            world.set_body_pose(rest)
            world.step()
            d = world.body_poses()[0][1] - PIVOT
            angles.append(np.arctan2(d[2], -d[1]))
    return np.array(angles)


def test_duplicate_joint_ranges_intersect_by_hand():
    # Gene's head strand: the joint アホ毛C_IF from the body above, x [-0.087, 0.524], z +-0.175, and its
    # reverse アホ毛C_IF- from the strand's body to the one above, x [-0.175, 0.524], z +-0.524: the
    # reverse, negated for the child, allows x [-0.524, 0.175]; both together x [-0.087, 0.175]
    z = np.zeros(3, np.float32)
    forward = JointRecord("toy", 0, "f", "", "spring_6dof", 0, 1, z, np.float32([1, 0, 0, 0]), z, z,
                          np.float32([-0.087, -0.052, -0.175]), np.float32([0.524, 0.052, 0.175]), z, z)
    backward = JointRecord("toy", 1, "f-", "", "spring_6dof", 1, 0, z, np.float32([1, 0, 0, 0]), z, z,
                           np.float32([-0.175, -0.052, -0.524]), np.float32([0.524, 0.052, 0.524]), z, z)
    lo, hi = intersect_bounds(joint_bounds(forward, False), joint_bounds(backward, True))
    np.testing.assert_allclose(lo, [-0.087, -0.052, -0.175], atol=1e-6)
    np.testing.assert_allclose(hi, [0.175, 0.052, 0.175], atol=1e-6)
    # a free axis (lower above upper) takes the other's range; ranges that do not overlap keep the first's
    lo, hi = intersect_bounds((np.array([1.0, -0.1, 0.0]), np.array([-1.0, 0.1, 0.1])),
                              (np.array([-0.2, 0.5, 0.3]), np.array([0.3, 0.6, 0.4])))
    np.testing.assert_allclose(lo, [-0.2, -0.1, 0.0])
    np.testing.assert_allclose(hi, [0.3, 0.1, 0.1])


def test_a_pendulum_stops_where_the_narrower_of_two_duplicate_joints_ends():
    # a joint allows the bob +-0.5 rad about x, its reverse duplicate only up to 0.2: swung at 3 rad/s
    # (gravity off) the bob stops at 0.2 rad (Bullet's hard limit lets it pass by about a step's turn,
    # 3 / 240 rad) with the ranges intersected, at 0.5 rad with the tree joint's own range
    # (the bob's angle about world X is minus the joint's x)
    both = -_swing(0.5, 3.0, 0.4, reverse_upper=0.2, duplicate_ranges=True)
    assert 0.2 <= both.max() < 0.2 + 2 * 3.0 / RATE
    own = -_swing(0.5, 3.0, 0.4, reverse_upper=0.2, duplicate_ranges=False)
    assert 0.5 - 1e-3 <= own.max() < 0.5 + 2 * 3.0 / RATE
    # a duplicate whose frame is turned (a quarter turn about y, its x the tree joint's z) limits
    # other axes: its ranges are not overlapped with the tree joint's, the bob reaches 0.5 rad
    turned = -_swing(0.5, 3.0, 0.4, reverse_upper=0.2, duplicate_ranges=True,
                     reverse_frame=(np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0))
    assert 0.5 - 1e-3 <= turned.max() < 0.5 + 2 * 3.0 / RATE
