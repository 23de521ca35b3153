"""The pybullet world of a character's own rigid bodies and joints (an MMD file), built from the
plan of :mod:`mimicbench.datagen.apparel.file_plan` and driven by the clip loop of :mod:`mimicbench.datagen.apparel.simulate`.

Time: fixed steps of ``1 / (clip fps * substeps)``, the substeps a frame from
:attr:`~mimicbench.datagen.apparel.params.SimParams.file_step_rate`; gravity 9.8 m/s^2 along -Y in metres
(MMD players use 9.8 x 10 units/s^2, which is 7.84 m/s^2 at 0.08 m per unit). The joints' error
reduction, the solver's iterations and sleeping are the players' (``SimParams.file_*``), and a clip
starts with the players' reset and warm-up (:meth:`FileWorld.reset`).
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mimicbench.datagen.apparel.file_plan import (CAPSULE_Z_TO_Y, ChainBuild, ChainPlan, bones_from_bodies, build_chain,
                                       collision_filter, plan_scene, rotation_xyzw, wxyz_rotation)
from mimicbench.datagen.apparel.body_damping import chain_jacobian, damped_joint_velocities, differs, keep_factors
from mimicbench.datagen.apparel.body_shapes import body_pieces
from mimicbench.datagen.apparel.capped_contacts import CappedContacts
from mimicbench.datagen.apparel.params import SimParams
from mimicbench.datagen.apparel.selection import dominant_bone
from mimicbench.datagen.apparel.setup import CharacterPhysics, simulated_record, substeps_for
from mimicbench.datagen.apparel.simulate import simulate_clip
from mimicbench.datagen.apparel.world import MOVING_PIECE_MASS, piece_velocities
from mimicbench.geometry.quaternion import quat_apply, quat_multiply
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

FILE_GRAVITY = 9.8  # m/s^2
FILE_PHYSICS_VERSION = "3"
ANCHOR_ACCEL = 500.0  # m/s^2: the anchor constraint's force limit per kilogram of anchor


def _shape(pb, body: RigidBodyRecord, cid: int) -> int:
    s = np.asarray(body.size, np.float64)
    if body.shape == "sphere":
        return pb.createCollisionShape(pb.GEOM_SPHERE, radius=max(s[0], 1e-4), physicsClientId=cid)
    if body.shape == "box":
        return pb.createCollisionShape(pb.GEOM_BOX, halfExtents=np.maximum(s, 1e-4).tolist(), physicsClientId=cid)
    if body.shape == "capsule":
        return pb.createCollisionShape(pb.GEOM_CAPSULE, radius=max(s[0], 1e-4), height=max(s[1], 1e-4),
                                       collisionFrameOrientation=rotation_xyzw(CAPSULE_Z_TO_Y), physicsClientId=cid)
    raise ValueError(f"rigid body {body.name}: shape {body.shape!r}; expected sphere, box or capsule")


class FileWorld:
    """One DIRECT pybullet client holding a character's file physics (:mod:`mimicbench.datagen.apparel.file_plan`),
    a :class:`~mimicbench.datagen.apparel.simulate.PhysicsWorld`.

    Args:
        bodies, joints: the character's records (dataset frame, rest pose).
        keypoints: (K, 3) rest bone heads, metres. parents: (K,) bone parents.
        dt: physics step, seconds. solver_iterations: Bullet's.
        metres_per_unit: the file's unit (for spring stiffness), metres.
        gravity: m/s^2 along -Y. apparel: (K,) bool, the only bones :meth:`clip_out` changes (None: all).
        max_speed: m/s, a faster body is an explosion.
        contact_frequency: rad/s; above 0 every dynamic body touches others through a critically
            damped contact spring of this frequency (stiffness m w^2, damping 2 m w, m its mass: it
            sinks g / w^2 under its own weight) instead of Bullet's rigid contacts
            (:attr:`~mimicbench.datagen.apparel.params.SimParams.file_contact_frequency`).
        erp: Bullet's non-contact error reduction (0..1, the share of a joint's error removed each
            step); None keeps Bullet's default (0.2).
        sleeping: whether Bullet may deactivate chains that stay still (players never let it).
        body_velocity: each static (bone-following) body is a body of
            :data:`~mimicbench.datagen.apparel.world.MOVING_PIECE_MASS` kg placed every step where the
            step before left it, with the speed that carries it to its bone's pose by the step's end
            (:func:`~mimicbench.datagen.apparel.world.piece_velocities`), as Bullet moves the players'
            kinematic bodies: contacts see the limb's speed. False: mass-0 bodies teleported to their
            poses, which contacts take as standing still. Static bodies never collide with each other
            (kinematic pairs in Bullet make no contact).
        duplicate_ranges: each tree joint's range is the overlap of its own and those of the other
            joints between the same two bodies, which the scene drops as duplicates
            (:func:`~mimicbench.datagen.apparel.file_plan.build_chain`); False: its own range.
        body_damping: each body of a chain whose bodies' dampings differ is damped by its own
            linear and angular damping after every step (:mod:`mimicbench.datagen.apparel.body_damping`,
            MMD's Bullet's per-body damping), that chain's multibody damping 0; False: every chain
            takes one damping, its bodies' rates averaged by mass.
        contact_cap: m/s^2; above 0, the contacts between bone-following bodies and chain links are
            :mod:`mimicbench.datagen.apparel.capped_contacts`' (one closest point a pair, the spring of
            ``contact_frequency`` seeing the body's own speed, the force capped at the link's mass
            times this), not Bullet's; 0: Bullet's. Needs ``contact_frequency`` above 0.
    Use as a context manager (the client is disconnected on exit).
    """

    def __init__(self, bodies: list[RigidBodyRecord], joints: list[JointRecord], keypoints: np.ndarray,
                 parents: np.ndarray, dt: float, solver_iterations: int = 30, metres_per_unit: float = 0.08,
                 gravity: float = FILE_GRAVITY, apparel: np.ndarray | None = None,
                 max_speed: float = SimParams.max_speed,
                 contact_frequency: float = SimParams.file_contact_frequency, erp: float | None = None,
                 sleeping: bool = False, body_velocity: bool = False,
                 duplicate_ranges: bool = SimParams.file_duplicate_ranges,
                 body_damping: bool = SimParams.file_body_damping,
                 contact_cap: float = SimParams.file_contact_cap):
        import pybullet

        if contact_cap > 0 and contact_frequency <= 0:
            raise ValueError(f"contact_cap {contact_cap} m/s^2 needs a contact spring: expected contact_frequency "
                             f"above 0, got {contact_frequency}")

        self.pb, pb = pybullet, pybullet
        self.bodies, self.joints = bodies, joints
        self.keypoints = np.asarray(keypoints, np.float64)
        self.parents = np.asarray(parents)
        self.apparel = np.ones(len(self.keypoints), bool) if apparel is None else np.asarray(apparel, bool)
        self.max_speed = float(max_speed)
        self.plan = plan_scene(bodies, joints)
        self.client = cid = pb.connect(pb.DIRECT)
        pb.resetSimulation(physicsClientId=cid)
        pb.setGravity(0.0, -gravity, 0.0, physicsClientId=cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSolverIterations=int(solver_iterations),
                                     deterministicOverlappingPairs=1, collisionFilterMode=0, physicsClientId=cid)
        if erp is not None:
            pb.setPhysicsEngineParameter(erp=float(erp), physicsClientId=cid)
        self.static = [i for i, b in enumerate(bodies) if b.mode == "static"]
        self.static_ids = []
        self.dt, self.gravity, self.body_velocity = float(dt), float(gravity), bool(body_velocity)
        for i in self.static:
            b = bodies[i]
            body = pb.createMultiBody(baseMass=MOVING_PIECE_MASS if self.body_velocity else 0.0,
                                      baseCollisionShapeIndex=_shape(pb, b, cid),
                                      basePosition=np.asarray(b.position, np.float64).tolist(),
                                      baseOrientation=rotation_xyzw(wxyz_rotation(b.rotation)), physicsClientId=cid)
            pb.setCollisionFilterGroupMask(body, -1, *collision_filter(b.collision_group, b.collision_mask),
                                           physicsClientId=cid)
            pb.changeDynamics(body, -1, lateralFriction=float(b.friction), restitution=float(b.restitution),
                              physicsClientId=cid)
            if self.body_velocity:
                pb.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0,
                                  activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
                for other in self.static_ids:
                    pb.setCollisionFilterPair(body, other, -1, -1, 0, physicsClientId=cid)
            self.static_ids.append(body)
        self._placed = np.full((len(self.static), 7), np.nan)  # (S, 7) where each static body was put last
        self.chains: list[tuple[ChainPlan, ChainBuild, int, int]] = []
        self.link_of: dict[int, tuple[int, int]] = {}  # body -> (multibody id, link index)
        with tempfile.TemporaryDirectory(prefix="mimicbench-file-physics-") as tmp:
            for c, plan in enumerate(self.plan.chains):
                build = build_chain(plan, bodies, joints, dt, metres_per_unit, duplicate_ranges=duplicate_ranges)
                path = Path(tmp) / f"chain{c}.urdf"
                path.write_text(build.urdf)
                mb = pb.loadURDF(str(path), basePosition=build.anchor_pos.tolist(),
                                 baseOrientation=rotation_xyzw(build.anchor_rot),
                                 flags=pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_MAINTAIN_LINK_ORDER
                                 | (pb.URDF_ENABLE_SLEEPING if sleeping else 0), physicsClientId=cid)
                pb.changeDynamics(mb, -1, linearDamping=build.damping[0], angularDamping=build.damping[1],
                                  activationState=(pb.ACTIVATION_STATE_ENABLE_SLEEPING if sleeping
                                                   else pb.ACTIVATION_STATE_DISABLE_SLEEPING), physicsClientId=cid)
                pb.setCollisionFilterGroupMask(mb, -1, 0, 0, physicsClientId=cid)
                for li, b in enumerate(plan.links):
                    rb = bodies[b]
                    pb.setCollisionFilterGroupMask(mb, li, *collision_filter(rb.collision_group, rb.collision_mask),
                                                   physicsClientId=cid)
                    pb.changeDynamics(mb, li, lateralFriction=float(rb.friction), restitution=float(rb.restitution),
                                      physicsClientId=cid)
                    if contact_frequency > 0:
                        w, mass = float(contact_frequency), pb.getDynamicsInfo(mb, li, physicsClientId=cid)[0]
                        pb.changeDynamics(mb, li, contactStiffness=mass * w * w, contactDamping=2.0 * mass * w,
                                          physicsClientId=cid)
                    if not build.fixed[li]:
                        pb.resetJointStateMultiDof(mb, li, build.rest_q[li], physicsClientId=cid)
                        gain, torque = build.gains[li]
                        pb.setJointMotorControlMultiDof(mb, li, pb.POSITION_CONTROL, targetPosition=build.rest_q[li],
                                                        targetVelocity=[0.0, 0.0, 0.0], positionGain=gain,
                                                        velocityGain=1.0 if gain > 0 else 0.0, force=torque,
                                                        physicsClientId=cid)
                    self.link_of[b] = (mb, li)
                constraint = pb.createConstraint(mb, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                                                 build.anchor_pos.tolist(), childFrameOrientation=rotation_xyzw(build.anchor_rot),
                                                 physicsClientId=cid)
                pb.changeConstraint(constraint, maxForce=ANCHOR_ACCEL * build.mass, physicsClientId=cid)
                self.chains.append((plan, build, mb, constraint))
        self.damped = []  # (chain, masses (L,), local inertias (L, 3), keep (L, 2)) per body-damped chain
        for c, (plan, build, mb, _) in enumerate(self.chains):
            lin = [float(bodies[b].linear_damping) for b in plan.links]
            ang = [float(bodies[b].angular_damping) for b in plan.links]
            if body_damping and differs(lin, ang):
                pb.changeDynamics(mb, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
                info = [pb.getDynamicsInfo(mb, li, physicsClientId=cid) for li in range(len(plan.links))]
                self.damped.append((c, np.array([i[0] for i in info]), np.array([i[2] for i in info]),
                                    keep_factors(lin, ang, self.dt)))
        self.contacts = None if contact_cap <= 0 else CappedContacts.attach(
            pb, cid, bodies, self.static, self.static_ids, [(plan.links, mb) for plan, _, mb, _ in self.chains],
            contact_frequency, contact_cap)
        self._static_now = np.zeros((len(self.static), 3))  # (S, 3) centres this step, metres
        self._static_speed = np.zeros((len(self.static), 2, 3))  # (S, 2, 3) linear m/s, angular rad/s
        static_index = {b: k for k, b in enumerate(self.static)}
        frames = {b: (mb, li, build.link_pos[li], build.link_rot[li])
                  for plan, build, mb, _ in self.chains for li, b in enumerate(plan.links)}
        for j in self.plan.loops:
            jr = joints[j]
            pos = np.asarray(jr.position, np.float64)
            ends = []
            for b in (int(jr.body_a), int(jr.body_b)):
                if b in frames:
                    mb, li, frame_pos, frame_rot = frames[b]
                else:
                    mb, li = self.static_ids[static_index[b]], -1
                    frame_pos, frame_rot = np.asarray(bodies[b].position, np.float64), wxyz_rotation(bodies[b].rotation)
                ends.append((mb, li, frame_rot.inv().apply(pos - frame_pos).tolist()))
            (ma, la, pa), (mc, lc, pc) = ends
            pb.createConstraint(ma, la, mc, lc, pb.JOINT_POINT2POINT, [0, 0, 0], pa, pc, physicsClientId=cid)
        rest = np.array([[*bodies[i].position, *bodies[i].rotation] for i in self.static], np.float64).reshape(-1, 7)
        self.static_bones = np.array([bodies[i].bone for i in self.static], int)
        bone = np.maximum(self.static_bones, 0)
        self._static_offset = rest[:, :3] - np.where(self.static_bones[:, None] >= 0, self.keypoints[bone], 0.0)
        self._static_rot = rest[:, 3:]
        self._anchor_rows = np.array([static_index[plan.anchor] for plan, *_ in self.chains], int)
        # bones whose pose the world reads: static bodies' bones
        self.driven_bones = np.array(sorted({int(b) for b in self.static_bones if b >= 0}), int)

    def static_poses(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World poses of the static bodies when bones are at ``pose`` (K, 7): (S, 3) positions and
        (S, 4) rotations (w, x, y, z); a body without a bone stays at rest."""
        has = self.static_bones >= 0
        rows = pose[np.maximum(self.static_bones, 0)]
        q = np.where(has[:, None], rows[:, :4], np.array([1.0, 0.0, 0.0, 0.0]))
        t = np.where(has[:, None], rows[:, 4:], 0.0)
        return t + quat_apply(q, self._static_offset), quat_multiply(q, self._static_rot)

    def set_body_pose(self, pose: np.ndarray) -> None:
        """Move static bodies and chain anchors with the bones at ``pose`` (K, 7) (w, x, y, z, t)."""
        pb, cid = self.pb, self.client
        positions, rotations = self.static_poses(np.asarray(pose, np.float64))
        xyzw = rotations[:, [1, 2, 3, 0]]
        placed = np.concatenate([positions, xyzw], axis=1)
        before = self._placed
        self._placed = placed
        if self.contacts is not None:  # the capped contacts' damping sees each body's own speed
            self._static_now = positions
            self._static_speed = piece_velocities(placed, before, self.dt, 0.0)
        if self.body_velocity:  # put where the last step left it, moving to this step's pose
            speed = piece_velocities(placed, before, self.dt, self.gravity).tolist()  # (S, 2, 3)
            start = np.where(np.isnan(before), placed, before)
            for k, body in enumerate(self.static_ids):
                pb.resetBasePositionAndOrientation(body, start[k, :3].tolist(), start[k, 3:].tolist(),
                                                   physicsClientId=cid)
                pb.resetBaseVelocity(body, speed[k][0], speed[k][1], physicsClientId=cid)
        else:
            for k, body in enumerate(self.static_ids):
                pb.resetBasePositionAndOrientation(body, positions[k].tolist(), xyzw[k].tolist(), physicsClientId=cid)
        positions, xyzw = positions.tolist(), xyzw.tolist()
        for (plan, build, mb, constraint), k in zip(self.chains, self._anchor_rows):
            pb.changeConstraint(constraint, jointChildPivot=positions[k], jointChildFrameOrientation=xyzw[k],
                                maxForce=ANCHOR_ACCEL * build.mass, physicsClientId=cid)

    def place_at(self, pose: np.ndarray) -> None:
        """Teleport every chain rigidly with its anchor, and every static body, to ``pose`` (before the
        first step; static bodies start there at rest)."""
        positions, rotations = self.static_poses(np.asarray(pose, np.float64))
        self._placed[:] = np.nan
        for (plan, build, mb, _), k in zip(self.chains, self._anchor_rows):
            self.pb.resetBasePositionAndOrientation(mb, positions[k].tolist(), rotations[k, [1, 2, 3, 0]].tolist(),
                                                    physicsClientId=self.client)
        self.set_body_pose(pose)

    def resettle(self, pose: np.ndarray) -> int:
        """Put each chain with a body faster than :attr:`max_speed` or a non-finite state back at rest on
        its anchor at body pose ``pose`` (K, 7): the base placed rigidly with its static body
        (:meth:`place_at`), every joint at its rest rotation (the motors' target), every velocity
        zero. Returns the number of chains put back."""
        pb, cid = self.pb, self.client
        positions, rotations = self.static_poses(np.asarray(pose, np.float64))
        count = 0
        for (plan, build, mb, _), k in zip(self.chains, self._anchor_rows):
            states = pb.getLinkStates(mb, list(range(len(plan.links))), computeLinkVelocity=1,
                                      computeForwardKinematics=1, physicsClientId=cid)
            numbers = np.array([s[0] + s[1] + s[6] for s in states], np.float64).reshape(-1, 10)
            if np.isfinite(numbers).all() and not (np.linalg.norm(numbers[:, 7:], axis=1) > self.max_speed).any():
                continue
            pb.resetBasePositionAndOrientation(mb, positions[k].tolist(), rotations[k, [1, 2, 3, 0]].tolist(),
                                               physicsClientId=cid)
            pb.resetBaseVelocity(mb, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
            for li in range(len(plan.links)):
                if not build.fixed[li]:
                    pb.resetJointStateMultiDof(mb, li, build.rest_q[li], targetVelocity=[0.0, 0.0, 0.0],
                                               physicsClientId=cid)
            count += 1
        return count

    def zero_velocities(self) -> None:
        """Set every chain's base and joint velocities to zero, its joints where they are."""
        pb, cid = self.pb, self.client
        for plan, build, mb, _ in self.chains:
            pb.resetBaseVelocity(mb, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
            for li in range(len(plan.links)):
                if not build.fixed[li]:
                    q = pb.getJointStateMultiDof(mb, li, physicsClientId=cid)[0]
                    pb.resetJointStateMultiDof(mb, li, q, targetVelocity=[0.0, 0.0, 0.0], physicsClientId=cid)

    def reset(self, pose: np.ndarray) -> None:
        """The players' reset at body pose ``pose`` (K, 7): every chain placed rigidly with its static
        body (:meth:`place_at`), its joints at their rest rotations, one step, then every velocity
        zeroed (Saba's reset: snap the bodies to their bones, step once, zero velocities and forces;
        Bullet clears applied forces after each step)."""
        pb, cid = self.pb, self.client
        self.place_at(pose)
        for plan, build, mb, _ in self.chains:
            for li in range(len(plan.links)):
                if not build.fixed[li]:
                    pb.resetJointStateMultiDof(mb, li, build.rest_q[li], targetVelocity=[0.0, 0.0, 0.0],
                                               physicsClientId=cid)
        self.zero_velocities()
        self.step()
        self.zero_velocities()

    def step(self) -> None:
        if self.contacts is not None:
            self.contacts.apply([mb for _, _, mb, _ in self.chains], self.static_ids, self._static_now,
                                self._static_speed)
        self.pb.stepSimulation(physicsClientId=self.client)
        for c, masses, inertia, keep in self.damped:
            self._damp_bodies(c, masses, inertia, keep)

    def _damp_bodies(self, c: int, masses: np.ndarray, inertia: np.ndarray, keep: np.ndarray) -> None:
        """Scale chain ``c``'s bodies' world velocities by their own factors ``keep`` (L, 2)
        (:func:`~mimicbench.datagen.apparel.body_damping.damped_joint_velocities`; masses (L,) kg,
        inertia (L, 3) the principal moments, kg m^2)."""
        pb, cid = self.pb, self.client
        plan, build, mb, _ = self.chains[c]
        links = list(range(len(plan.links)))
        states = pb.getLinkStates(mb, links, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid)
        joints = pb.getJointStatesMultiDof(mb, links, physicsClientId=cid)
        free = np.array([not f for f in build.fixed])
        frames = Rotation.from_quat([s[1] for s in states]).as_matrix()
        jac = chain_jacobian(plan.link_parents, free, np.array([s[0] for s in states]),
                             np.array([s[4] for s in states]), frames)
        qd = np.concatenate([np.asarray(j[1], np.float64) if f else np.zeros(3) for j, f in zip(joints, free)])
        world_inertia = np.einsum("lab,lb,lcb->lac", frames, inertia, frames)
        new = damped_joint_velocities(jac, np.array([s[6] + s[7] for s in states]), qd, masses, world_inertia, keep)
        for li in links:
            if free[li]:
                pb.resetJointStateMultiDof(mb, li, joints[li][0], targetVelocity=new[3 * li:3 * li + 3].tolist(),
                                           physicsClientId=cid)

    def start(self) -> None:
        """Nothing to ready: the joints' motors were set when the world was built."""

    def follow(self, poses: np.ndarray, per_frame: int):
        """Place the static bodies at each of ``poses`` (S, K, 7) and step; yield every ``per_frame`` steps."""
        for s, pose in enumerate(poses):
            self.set_body_pose(pose)
            self.step()
            if (s + 1) % per_frame == 0:
                yield (s + 1) // per_frame - 1

    def read(self) -> tuple[tuple[np.ndarray, np.ndarray], float]:
        """Simulated bodies' centres (B, 3), rotations (B, 4) (w, x, y, z), chain order; fastest speed (m/s)."""
        positions, rotations, speed = self.body_poses()
        return (np.array(list(positions.values())).reshape(-1, 3),
                np.array(list(rotations.values())).reshape(-1, 4)), speed

    def clip_out(self, transforms: np.ndarray, states: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """(F, K, 7) float32: ``transforms`` with its apparel bones from the bodies of :meth:`read`'s
        ``states`` (one a frame; :func:`~mimicbench.datagen.apparel.file_plan.bones_from_bodies`)."""
        out = np.array(transforms, np.float32, copy=True)
        clip, order = np.asarray(transforms, np.float64), list(self.link_of)  # the bodies in read order
        for f, (positions, rotations) in enumerate(states):
            bones = bones_from_bodies(self.bodies, self.parents, self.keypoints, clip[f], dict(zip(order, positions)),
                                      dict(zip(order, rotations)), self.apparel)
            out[f, self.apparel] = bones[self.apparel]
        return out

    def body_poses(self) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray], float]:
        """World pose of every simulated body and the fastest link speed (m/s).

        Returns ({body: (3,) centre}, {body: (4,) rotation (w, x, y, z)}, speed)."""
        pb, cid = self.pb, self.client
        positions, rotations, speed = {}, {}, 0.0
        for plan, build, mb, _ in self.chains:
            states = pb.getLinkStates(mb, list(range(len(plan.links))), computeLinkVelocity=1,
                                      computeForwardKinematics=1, physicsClientId=cid)
            for li, (b, s) in enumerate(zip(plan.links, states)):
                x, y, z, w = (Rotation.from_quat(s[5]) * build.body_rot[li]).as_quat()
                positions[b] = np.array(s[0], np.float64)  # the inertial frame's origin: the body's centre
                rotations[b] = np.array([w, x, y, z], np.float64)
                speed = max(speed, float(np.linalg.norm(s[6])))
        return positions, rotations, speed

    def close(self) -> None:
        if self.client is not None:
            self.pb.disconnect(physicsClientId=self.client)
            self.client = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def simulate_file_motion(record, bodies: list[RigidBodyRecord], joints: list[JointRecord], motion,
                         apparel_bones: np.ndarray, apparel_vertices: np.ndarray, physics_fps: float, relax: int,
                         sim: SimParams) -> tuple[object, dict]:
    """The simulated clip of ``motion`` (a :class:`~mimicbench.schemas.motion.MotionRecord`) with the
    character's own bodies and joints, as a new motion ``<clip>@sim``, and its quality
    (:mod:`mimicbench.datagen.apparel.quality`, plus ``physics: "file"`` and the scene's counts).

    ``sim``: :class:`~mimicbench.datagen.apparel.params.SimParams` (the ``file_*`` settings, speed bound,
    re-settles; gravity is :data:`FILE_GRAVITY`). ``physics_fps`` (the stage's ``--fps``) is not
    used: the step rate is ``sim.file_step_rate``.
    """
    steps = substeps_for(sim.file_step_rate, motion.fps)
    unit = float(((record.meta or {}).get("mmd") or {}).get("metres_per_unit", 0.08))
    apparel_bones = np.asarray(apparel_bones, bool)
    with FileWorld(bodies, joints, record.keypoints, record.parents, 1.0 / (motion.fps * steps),
                   sim.file_solver_iterations, unit, apparel=apparel_bones, max_speed=sim.max_speed,
                   contact_frequency=sim.file_contact_frequency, erp=sim.file_erp,
                   sleeping=sim.file_sleeping, body_velocity=sim.file_body_velocity,
                   duplicate_ranges=sim.file_duplicate_ranges, body_damping=sim.file_body_damping,
                   contact_cap=sim.file_contact_cap) as world:
        simulated = simulate_clip(world, motion.transforms, steps, relax, sim.max_resettles, warmup=sim.file_warmup)
        plan = world.plan
    pieces = body_pieces(record.vertices, record.keypoints, dominant_bone(record.weights, record.num_joints),
                         ~apparel_bones)
    physics = CharacterPhysics(pieces, [], apparel_bones, np.asarray(apparel_vertices, bool))
    return simulated_record(record, physics, motion, simulated, f"apparel:pybullet-file@{FILE_PHYSICS_VERSION}", {
        "physics": "file", "substeps": steps, "relax_frames": int(relax), "gravity": FILE_GRAVITY,
        "step_rate": motion.fps * steps, "erp": sim.file_erp, "solver_iterations": sim.file_solver_iterations,
        "sleeping": sim.file_sleeping, "warmup": sim.file_warmup,
        **({"body_velocity": True} if sim.file_body_velocity else {}),  # recorded only when on
        **({"duplicate_ranges": True} if sim.file_duplicate_ranges else {}),
        **({"body_damping": True} if sim.file_body_damping else {}),
        **({"contact_cap": sim.file_contact_cap} if sim.file_contact_cap > 0 else {}),
        "links": sum(len(c.links) for c in plan.chains), "chains": len(plan.chains),
        "static_bodies": sum(b.mode == "static" for b in bodies), "loop_constraints": len(plan.loops),
        "dropped_joints": len(plan.dropped), "unanchored_bodies": len(plan.unanchored)})
