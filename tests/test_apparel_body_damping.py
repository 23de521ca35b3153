"""Per-body damping in the file physics (``SimParams.file_body_damping``): what pybullet damps per
link and per multibody (pendulums against their analytic decay), the chain's velocity Jacobian and
the damped joint velocities by hand, and a two-body pendulum whose bodies keep their own dampings.

A pendulum with a velocity damping force ``-c m v`` obeys ``theta'' + c theta' + (g / L) theta = 0``
(point mass): its amplitude decays as ``exp(-c t / 2)``; a joint damping torque ``-b theta'`` on a
moment ``I = m L^2`` decays it as ``exp(-b t / (2 I))``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mimicbench.datagen.apparel.body_damping import chain_jacobian, damped_joint_velocities, differs, keep_factors
from mimicbench.datagen.apparel.file_physics import FileWorld
from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

pybullet = pytest.importorskip("pybullet")

RATE = 240.0
ARM = 0.5  # metres from a pivot to a pendulum's mass
TWO_PENDULUMS = """<robot name="two"><link name="base"><inertial><mass value="0"/>
<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>
{links}</robot>"""
PENDULUM = """<link name="l{i}"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
<inertia ixx="1e-6" iyy="1e-6" izz="1e-6" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j{i}" type="continuous"><parent link="base"/><child link="l{i}"/><origin xyz="{x} 0 0"/>
<axis xyz="0 1 0"/></joint>"""


def _decay_rate(t: np.ndarray, angle: np.ndarray) -> float:
    """The amplitude's decay rate (1/s): the slope of the log of the swing's peaks."""
    peaks = [i for i in range(1, len(angle) - 1) if angle[i] > angle[i - 1] and angle[i] >= angle[i + 1]]
    assert len(peaks) >= 3, "expected at least three swings"
    return -float(np.polyfit(t[peaks], np.log(angle[peaks]), 1)[0])


def _two_pendulums(tmp_path, set_dynamics, seconds=10.0):
    """Two independent 1 kg point pendulums (ARM long, 2 m apart) as links of one fixed-base multibody,
    both started 0.01 rad out; ``set_dynamics(pb, cid, body)`` damps them. Returns each link's
    amplitude decay rate (1/s)."""
    path = tmp_path / "two.urdf"
    path.write_text(TWO_PENDULUMS.format(links="".join(PENDULUM.format(i=i, x=2 * i) for i in range(2))))
    pb = pybullet
    cid = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -9.8, physicsClientId=cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=1.0 / RATE, physicsClientId=cid)
        body = pb.loadURDF(str(path), useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        for li in range(2):
            pb.setJointMotorControl2(body, li, pb.VELOCITY_CONTROL, force=0, physicsClientId=cid)
            pb.resetJointState(body, li, 0.01, physicsClientId=cid)
            pb.changeDynamics(body, li, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0, physicsClientId=cid)
        set_dynamics(pb, cid, body)
        angles = []
        for _ in range(int(seconds * RATE)):
            pb.stepSimulation(physicsClientId=cid)
            angles.append([pb.getJointState(body, li, physicsClientId=cid)[0] for li in range(2)])
    finally:
        pb.disconnect(cid)
    angles = np.array(angles)
    t = np.arange(1, len(angles) + 1) / RATE
    return [_decay_rate(t, angles[:, li]) for li in range(2)]


def test_pybullet_damps_a_multibody_as_a_whole_whichever_link_is_named(tmp_path):
    # linear damping c = 2 /s named on link 1 only: both pendulums decay as exp(-c t / 2) = exp(-t)
    rates = _two_pendulums(tmp_path, lambda pb, cid, body: pb.changeDynamics(
        body, 1, linearDamping=2.0, angularDamping=0.0, physicsClientId=cid))
    assert rates[0] == pytest.approx(1.0, rel=0.02)
    assert rates[1] == pytest.approx(1.0, rel=0.02)


def test_pybullet_joint_damping_is_per_link(tmp_path):
    # joint damping b = 0.5 N m s on link 1 only (I = m L^2 = 0.25 kg m^2): it decays at b / (2 I) = 1 /s,
    # link 0 does not decay
    rates = _two_pendulums(tmp_path, lambda pb, cid, body: pb.changeDynamics(
        body, 1, jointDamping=0.5, physicsClientId=cid))
    assert abs(rates[0]) < 1e-3
    assert rates[1] == pytest.approx(1.0, rel=0.02)


def test_keep_factors_and_differs_by_hand():
    # (1 - d) ** dt: d = 0.5 over half a second keeps 0.5 ** 0.5; d = 1 is taken as 0.999
    np.testing.assert_allclose(keep_factors([0.5, 1.0], [0.0, 0.75], 0.5),
                               [[math.sqrt(0.5), 1.0], [math.sqrt(0.001), 0.5]])
    assert differs([0.5, 0.9], [0.5, 0.5]) and not differs([0.5, 0.5], [0.2, 0.2])
    with pytest.raises(ValueError, match="damping"):
        keep_factors([-0.1], [0.0], 0.01)


def test_chain_jacobian_by_hand():
    # link 0 pivots at the origin, its centre at (0.5, 0, 0); link 1 pivots at (1, 0, 0), centre (1.5, 0, 0)
    pivots = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    centres = np.array([[0.5, 0.0, 0.0], [1.5, 0.0, 0.0]])
    quarter = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # a quarter turn about x
    jac = chain_jacobian([-1, 0], np.array([True, True]), centres, pivots, np.stack([quarter, np.eye(3)]))
    # joint 0 turning at 1 rad/s about its frame's y, which is world z: both links turn about z at the origin
    v = jac @ np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(v, [[0.0, 0.5, 0.0, 0.0, 0.0, 1.0], [0.0, 1.5, 0.0, 0.0, 0.0, 1.0]], atol=1e-12)
    # joint 1 about world z: link 1 only, about its pivot
    v = jac @ np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(v, [[0.0] * 6, [0.0, 0.5, 0.0, 0.0, 0.0, 1.0]], atol=1e-12)
    # a fixed joint 1: no columns of its own; link 1 still turns with joint 0
    jac = chain_jacobian([-1, 0], np.array([True, False]), centres, pivots, np.stack([np.eye(3), np.eye(3)]))
    assert not jac[:, :, 3:].any()
    np.testing.assert_allclose(jac[1] @ [1.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0, 0.0], atol=1e-12)


def test_damped_velocities_of_one_link_by_hand():
    # one link of mass m, centre L from its pivot, moment I about the centre, turning at w about z: its
    # kept linear and angular speeds k_l w L and k_a w; the joint's nearest speed in kinetic energy is
    # w (m L^2 k_l + I k_a) / (m L^2 + I)
    m, arm, inertia, w, k_l, k_a = 2.0, 0.3, 0.05, 1.5, 0.4, 0.9
    jac = chain_jacobian([-1], np.array([True]), np.array([[arm, 0.0, 0.0]]), np.zeros((1, 3)), np.eye(3)[None])
    qd = np.array([0.0, 0.0, w])
    new = damped_joint_velocities(jac, (jac @ qd).reshape(1, 6), qd, np.array([m]), inertia * np.eye(3)[None],
                                  np.array([[k_l, k_a]]))
    expected = w * (m * arm ** 2 * k_l + inertia * k_a) / (m * arm ** 2 + inertia)
    np.testing.assert_allclose(new, [0.0, 0.0, expected], atol=1e-12)
    # the anchor's share is kept: a link carried at 1 m/s along y by its anchor and not turning keeps
    # a joint speed of 0 when nothing is damped
    carried = np.array([[0.0, 1.0, 0.0, 0.0, 0.0, 0.0]])
    new = damped_joint_velocities(jac, carried, np.zeros(3), np.array([m]), inertia * np.eye(3)[None],
                                  np.ones((1, 2)))
    np.testing.assert_allclose(new, 0.0, atol=1e-12)


def test_damped_velocities_never_add_kinetic_energy():
    # random chains of four links with the anchor at rest: each factor in [0, 1] never raises the
    # kinetic energy q'^T M q' (M = J^T W J), and factors of 1 change nothing
    rng = np.random.default_rng(7)
    for _ in range(20):
        parents = [-1, 0, 1, 1]
        pivots = rng.normal(size=(4, 3))
        centres = pivots + rng.normal(size=(4, 3)) * 0.2
        frames = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(4)])
        free = np.array([True, True, False, True])
        jac = chain_jacobian(parents, free, centres, pivots, frames)
        masses = rng.uniform(0.05, 5.0, 4)
        inertias = np.stack([np.diag(rng.uniform(1e-4, 1e-2, 3)) for _ in range(4)])
        qd = rng.normal(size=12) * np.repeat(free, 3)
        velocities = np.einsum("lrc,c->lr", jac, qd)

        def energy(x):
            v = np.einsum("lrc,c->lr", jac, x)
            return (masses * (v[:, :3] ** 2).sum(1)).sum() + np.einsum("la,lab,lb->", v[:, 3:], inertias, v[:, 3:])

        keep = rng.uniform(0.0, 1.0, (4, 2))
        new = damped_joint_velocities(jac, velocities, qd, masses, inertias, keep)
        assert energy(new) <= energy(qd) * (1 + 1e-9)
        np.testing.assert_allclose(damped_joint_velocities(jac, velocities, qd, masses, inertias, np.ones((4, 2))),
                                   qd, atol=1e-9)


def _two_body_pendulum():
    """A static 2 cm sphere at the pivot; a 1 kg, 2 cm sphere (damping 0.5) ARM below it on a free
    spherical joint; a second 1 kg, 2 cm sphere (damping 0.9) 2 x ARM below, joined to the first by a
    joint with every range locked (a fixed joint). No collisions."""
    pivot = np.array([0.0, 2.0, 0.0])
    z = np.zeros(3, np.float32)

    def body(i, pos, mode, damping):
        return RigidBodyRecord("toy", i, f"b{i}", "", i, "sphere", np.float32([0.02, 0, 0]), np.float32(pos),
                               np.float32([1, 0, 0, 0]), 1.0, damping, damping, 0.0, 0.5, i, 0, mode)

    points = [pivot, pivot - [0.0, ARM, 0.0], pivot - [0.0, 2 * ARM, 0.0]]
    bodies = [body(0, points[0], "static", 0.0), body(1, points[1], "dynamic", 0.5), body(2, points[2], "dynamic", 0.9)]
    free_lo, free_hi = np.float32([1.0, 1.0, 1.0]), np.float32([-1.0, -1.0, -1.0])
    joints = [JointRecord("toy", 0, "swing", "", "spring_6dof", 0, 1, np.float32(points[0]), np.float32([1, 0, 0, 0]),
                          z, z, free_lo, free_hi, z, z),
              JointRecord("toy", 1, "weld", "", "spring_6dof", 1, 2, np.float32(points[1]), np.float32([1, 0, 0, 0]),
                          z, z, z, z, z, z)]
    return bodies, joints, np.array(points)


def _pendulum_decay(body_damping: bool) -> float:
    """The two-body pendulum's amplitude decay rate (1/s), started at rest turning at 0.1 rad/s."""
    bodies, joints, keypoints = _two_body_pendulum()
    rest = rest_transforms(keypoints).astype(np.float64)
    angles = []
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0, 1]), 1.0 / RATE, 30, 0.08,
                   apparel=np.array([False, True, True]), max_speed=1e6, body_damping=body_damping) as world:
        world.reset(rest)
        plan, build, mb, _ = world.chains[0]
        assert build.fixed == [False, True]
        pb, cid = world.pb, world.client
        q = pb.getJointStateMultiDof(mb, 0, physicsClientId=cid)[0]
        pb.resetJointStateMultiDof(mb, 0, q, targetVelocity=[0.0, 0.1, 0.0], physicsClientId=cid)
        for _ in range(int(8 * RATE)):
            world.set_body_pose(rest)
            world.step()
            d = world.body_poses()[0][1] - keypoints[0]
            angles.append(np.arctan2(d[2], -d[1]))
    angles = np.abs(np.array(angles))
    return _decay_rate(np.arange(1, len(angles) + 1) / RATE, angles)


def test_each_body_keeps_its_own_damping_on_a_two_body_pendulum():
    # rates c = -ln(1 - d): 0.693 /s at ARM and 2.303 /s at 2 ARM (1 kg each, moments 0.4 m r^2 about
    # their centres). Each body damped by its own: the swing loses c_eff = sum (m L^2 + I) c / sum (m L^2
    # + I) = 1.98 /s, its amplitude exp(-c_eff t / 2); one multibody damping (the rates' mass mean,
    # 1.50 /s) gives 0.75 /s
    c = np.array([-math.log(0.5), -math.log(0.1)])
    moment = np.array([ARM ** 2, (2 * ARM) ** 2]) + 0.4 * 0.02 ** 2
    assert _pendulum_decay(True) == pytest.approx(0.5 * (moment * c).sum() / moment.sum(), rel=0.03)
    assert _pendulum_decay(False) == pytest.approx(0.5 * c.mean(), rel=0.03)
