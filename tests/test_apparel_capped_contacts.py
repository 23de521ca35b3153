"""The capped contact's force law (datagen/apparel/capped_contacts.py) against hand-computed values."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.apparel.capped_contacts import bounding_radius, contact_force, touches
from mimicbench.schemas.rigid_body import RigidBodyRecord

UP = np.array([0.0, 1.0, 0.0])  # out of the body towards the link


def test_a_resting_link_is_pushed_by_the_spring_alone():
    # 2 kg sunk 1 cm at 75 rad/s: 2 * 75^2 * 0.01 = 112.5 N straight out
    np.testing.assert_allclose(contact_force(0.01, UP, np.zeros(3), 2.0, 75.0, 0.5, 0.0), [0.0, 112.5, 0.0])


def test_damping_acts_on_the_speed_into_the_body_and_never_pulls():
    # moving 0.1 m/s deeper adds 2 * 2 * 75 * 0.1 = 30 N; leaving at 1 m/s (300 N of damping
    # against 112.5 of spring) gives no force at all
    np.testing.assert_allclose(contact_force(0.01, UP, -0.1 * UP, 2.0, 75.0, 0.0, 0.0), [0.0, 142.5, 0.0])
    np.testing.assert_array_equal(contact_force(0.01, UP, 1.0 * UP, 2.0, 75.0, 0.5, 0.0), np.zeros(3))


def test_the_cap_limits_the_push_per_kilogram_and_friction_with_it():
    # capped at 20 m/s^2 on 2 kg: 40 N; sliding fast along X with mu 0.5: 20 N against the slide
    force = contact_force(0.01, UP, np.array([3.0, 0.0, 0.0]), 2.0, 75.0, 0.5, 20.0)
    np.testing.assert_allclose(force, [-20.0, 40.0, 0.0])


@pytest.mark.parametrize("slide, expected", [(1.0, 56.25), (0.01, 3.0)])
def test_friction_is_coulomb_when_sliding_and_viscous_below(slide, expected):
    # mu 0.5 of 112.5 N is 56.25 N; at 0.01 m/s the viscous limit 2 m w v = 3 N is smaller
    force = contact_force(0.01, UP, np.array([0.0, 0.0, slide]), 2.0, 75.0, 0.5, 0.0)
    np.testing.assert_allclose(force, [0.0, 112.5, -expected])


def _record(shape, size, group, mask):
    return RigidBodyRecord("toy", 0, "b", "", 0, shape, np.float32(size), np.zeros(3, np.float32),
                           np.float32([1, 0, 0, 0]), 1.0, 0.0, 0.0, 0.0, 0.5, group, mask, "dynamic")


def test_bounding_radius_and_collision_masks():
    assert bounding_radius(_record("sphere", [0.1, 0, 0], 0, 0)) == pytest.approx(0.1)
    assert bounding_radius(_record("box", [0.03, 0.04, 0.0], 0, 0)) == pytest.approx(0.05)
    assert bounding_radius(_record("capsule", [0.02, 0.1, 0], 0, 0)) == pytest.approx(0.07)
    a, b = _record("sphere", [0.1, 0, 0], 1, 0xFFFF), _record("sphere", [0.1, 0, 0], 3, 0xFFFF & ~(1 << 1))
    assert not touches(a, b) and not touches(b, a)
    assert touches(a, _record("sphere", [0.1, 0, 0], 3, 0xFFFF))


@pytest.mark.parametrize("past_centre", [0.0, 0.5])
def test_pybullets_world_frame_force_on_a_link_turns_it_about_the_point_it_is_applied_at(past_centre):
    # the contacts push a multibody link at a world point: a 1 kg bob 0.5 m from a Z hinge, pushed
    # along Y with 1 N at its centre and 0.5 m past it, turns at torque / moment: (0.5 + past) / 0.25
    # rad/s^2 (the bob's own moment, 2/5 m r^2 at r 1 cm, added)
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, 0, physicsClientId=cid)
        dt = 1.0 / 240.0
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, physicsClientId=cid)
        ball = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.01, physicsClientId=cid)
        body = pb.createMultiBody(0, -1, basePosition=[0, 0, 0], linkMasses=[1.0], linkCollisionShapeIndices=[ball],
                                  linkVisualShapeIndices=[-1], linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                                  linkInertialFramePositions=[[0.5, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                                  linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]],
                                  physicsClientId=cid)
        pb.setJointMotorControl2(body, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        pb.applyExternalForce(body, 0, [0, 1, 0], [0.5 + past_centre, 0, 0], pb.WORLD_FRAME, physicsClientId=cid)
        pb.stepSimulation(physicsClientId=cid)
        turning = pb.getJointState(body, 0, physicsClientId=cid)[1] / dt
    finally:
        pb.disconnect(cid)
    assert turning == pytest.approx((0.5 + past_centre) / (0.25 + 0.4 * 1e-4), rel=1e-3)


def test_a_cap_without_a_contact_spring_is_refused_with_the_field_named():
    from mimicbench.datagen.apparel.params import params_from_json
    from mimicbench.schemas.errors import UserError

    with pytest.raises(UserError, match="file_contact_cap.*file_contact_frequency above 0"):
        params_from_json({"simulation": {"file_contact_cap": 20, "file_contact_frequency": 0}})
    assert params_from_json({"simulation": {"file_contact_cap": 20}}).simulation.file_contact_cap == 20
