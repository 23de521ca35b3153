"""The pybullet world of one character: body pieces that follow the clip and dynamic apparel chains.

Each body piece is a convex hull placed every substep where it ended the last one and given the
speed that carries it to its bone's pose by the step's end (``piece_velocity``,
:func:`piece_velocities`), so that Bullet's contacts see a limb's speed; with ``piece_velocity`` off, a
mass-0 hull placed at its bone's pose (Bullet takes it as standing still); with ``piece_mass`` > 0
(:class:`~mimicbench.datagen.apparel.params.SimParams`), a body of that mass carried there by a fixed constraint
(slower: the constraints join the solver). Each chain
is a multibody loaded from its URDF (:mod:`mimicbench.datagen.apparel.urdf`) whose anchor (the base) has mass
and is carried the same way (``changeConstraint``; a teleported base would move the whole chain
rigidly, and it would never swing). Springs toward rest: torques for every joint at once
(:mod:`mimicbench.datagen.apparel.springs`, compiled in :mod:`mimicbench.datagen.apparel.joint_kernel`), one call per
chain; after every step each joint past its swing cone or twist limit is put back onto it and
stopped there (:meth:`ApparelWorld._after_step`). Chains on one body bone share one multibody
(:func:`~mimicbench.datagen.apparel.chain_spec.merged_by_anchor`); a world is reused across a character's
clips (:meth:`ApparelWorld.reset`). Each link collides as the convex hull of its bone's vertices
(:mod:`mimicbench.datagen.apparel.chains`); contact and constraint ERP and the joint speed bound are in
:class:`~mimicbench.datagen.apparel.params.SimParams`.

Collision: chain links meet the body pieces and, where both ask for it, other chains; see
:meth:`ApparelWorld._exclude_rest_overlaps` and :meth:`ApparelWorld._root_hulls_clearing_body`.
"""
from __future__ import annotations

import dataclasses
import itertools
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mimicbench.datagen.apparel.body_shapes import BodyPiece, hull_points
from mimicbench.datagen.apparel.chain_spec import ChainSpec, merged_by_anchor
from mimicbench.datagen.apparel.joint_kernel import joint_torques
from mimicbench.datagen.apparel.params import SimParams
from mimicbench.datagen.apparel.springs import Springs
from mimicbench.datagen.apparel.urdf import bone_frame, chain_urdf, hull_obj
from mimicbench.geometry.quaternion import quat_apply, quat_conjugate, quat_multiply

BODY_GROUP, BODY_MASK = 0b01, 0b10
REST_CONTACT_MARGIN = 0.002  # metres: closer than this at rest counts as overlapping
CLEARING_MARGINS = (0.0, 0.005, 0.01, 0.02)  # metres: hull points this far outside the body are kept
PIECE_ACCEL = 2000.0  # m/s^2: a piece's constraint's force limit per kilogram
MOVING_PIECE_MASS = 1000.0  # kg of a piece given its speed each step (SimParams.piece_velocity): a link's
# contact moves it by a few micrometres a second
MAX_IDLE_CLIENTS = 1  # pybullet clients a process keeps for its next worlds
_IDLE_CLIENTS: list[int] = []  # DIRECT clients of closed worlds, emptied by the next world (resetSimulation)


def xyzw(q_wxyz) -> list[float]:
    """A (w, x, y, z) quaternion as pybullet's (x, y, z, w) list."""
    return [float(q_wxyz[1]), float(q_wxyz[2]), float(q_wxyz[3]), float(q_wxyz[0])]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of (n, 3) arrays, each component computed as ``numpy.cross`` does (the same bytes)
    without its per-call overhead (it runs every frame)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors v (n, 3) rotated by unit quaternions q (n, 4) (w, x, y, z): v + 2 w (u x v) + 2 u x (u x v)."""
    w, u = q[:, :1], q[:, 1:]
    uv = _cross(u, v)
    return v + 2.0 * (w * uv + _cross(u, uv))


def piece_velocities(placed: np.ndarray, before: np.ndarray, dt: float, gravity: float) -> np.ndarray:
    """(..., 2, 3) the linear (m/s) and angular (rad/s, world frame) velocities that carry body pieces
    from placements ``before`` (..., 7) (position, quaternion x, y, z, w) to ``placed`` (..., 7) in
    ``dt`` seconds, with ``gravity`` dt (m/s) added upward: Bullet adds gravity's pull to a body's speed
    before it solves the contacts, so the contacts see the limb's speed. A placement without one before
    it (NaN) gets none."""
    placed = np.asarray(placed, np.float64)
    before = np.where(np.isnan(before), placed, before)
    linear = (placed[..., :3] - before[..., :3]) / dt
    linear[..., 1] += gravity * dt
    turn = Rotation.from_quat(placed[..., 3:].reshape(-1, 4)) * Rotation.from_quat(before[..., 3:].reshape(-1, 4)).inv()
    angular = turn.as_rotvec().reshape(linear.shape) / dt
    return np.stack([linear, angular], axis=-2)


@dataclass
class ChainBody:
    """A loaded chain: its spec, multibody id, anchor constraint id, and the anchor's rest offset."""

    spec: ChainSpec
    body: int
    constraint: int
    anchor_offset: np.ndarray  # (3,) root head minus anchor bone head, at rest


class ApparelWorld:
    """One DIRECT pybullet client holding a character's body pieces and chains, a
    :class:`~mimicbench.datagen.apparel.simulate.PhysicsWorld`.

    Args:
        keypoints: (K, 3) rest joint heads, metres. pieces: body pieces. chains: apparel chains.
        sim: scene settings. dt: physics step, seconds.
    Use as a context manager (the client is handed back on exit, :meth:`close`).
    """

    def __init__(self, keypoints: np.ndarray, pieces: list[BodyPiece], chains: list[ChainSpec], sim: SimParams,
                 dt: float):
        import pybullet

        self.pb = pybullet
        self.keypoints = np.asarray(keypoints, np.float64)
        self.pieces = pieces
        self.sim = sim
        self.client = _IDLE_CLIENTS.pop() if _IDLE_CLIENTS else pybullet.connect(pybullet.DIRECT)
        pb, cid = pybullet, self.client
        pb.resetSimulation(physicsClientId=cid)  # an idle client's previous world goes
        pb.setGravity(0.0, -sim.gravity, 0.0, physicsClientId=cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSolverIterations=int(sim.solver_iterations),
                                     contactERP=float(sim.contact_erp), erp=float(sim.constraint_erp),
                                     deterministicOverlappingPairs=1, collisionFilterMode=0,
                                     physicsClientId=cid)  # mode 0: two bodies collide when each one's group is in the other's mask
        self.piece_ids, self._piece_constraints = [], []
        self._moving_pieces = sim.piece_mass == 0 and sim.piece_velocity  # placed and given their speed each step
        mass = float(sim.piece_mass) if sim.piece_mass > 0 else MOVING_PIECE_MASS if self._moving_pieces else 0.0
        for piece in pieces:
            shape = pb.createCollisionShape(pb.GEOM_MESH, vertices=piece.points.tolist(), physicsClientId=cid)
            head = self.keypoints[piece.bone].tolist()
            body = pb.createMultiBody(baseMass=mass, baseCollisionShapeIndex=shape, basePosition=head,
                                      physicsClientId=cid)
            pb.setCollisionFilterGroupMask(body, -1, BODY_GROUP, BODY_MASK, physicsClientId=cid)
            self.piece_ids.append(body)
            if mass > 0:
                pb.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0,
                                  activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
            if sim.piece_mass > 0:
                held = pb.createConstraint(body, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0], head,
                                           physicsClientId=cid)
                pb.changeConstraint(held, maxForce=sim.piece_mass * PIECE_ACCEL, physicsClientId=cid)
                self._piece_constraints.append(held)
        self.chains: list[ChainBody] = []
        with tempfile.TemporaryDirectory(prefix="mimicbench-apparel-") as tmp:
            for i, chain in enumerate(merged_by_anchor(chains)):
                root_head = np.asarray(chain.links[0].head, np.float64)
                chain = self._root_hulls_clearing_body(chain)
                body = self._load(Path(tmp) / f"chain{i}.urdf", chain, root_head)
                offsets = self._root_offsets_clearing_body(body, chain)
                if offsets is not None:  # reloaded under a new name: pybullet caches a file's shapes by path
                    pb.removeBody(body, physicsClientId=cid)
                    body = self._load(Path(tmp) / f"chain{i}-clear.urdf", chain, root_head, offsets)
                self._set_dynamics(body, chain)
                constraint = pb.createConstraint(body, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                                                 root_head.tolist(), physicsClientId=cid)
                pb.changeConstraint(constraint, maxForce=float(sim.anchor_force), physicsClientId=cid)
                anchor = self.keypoints[chain.anchor_bone] if chain.anchor_bone >= 0 else np.zeros(3)
                self.chains.append(ChainBody(chain, body, constraint, root_head - anchor))
        self._anchored = [i for i, c in enumerate(self.chains) if c.spec.anchor_bone >= 0]
        self.driven_bones = np.array(sorted({p.bone for p in pieces} | {c.spec.anchor_bone for c in self.chains
                                                                         if c.spec.anchor_bone >= 0}), int)
        self._anchor_bones = np.array([self.chains[i].spec.anchor_bone for i in self._anchored], int)
        self._anchor_offsets = np.array([self.chains[i].anchor_offset for i in self._anchored]).reshape(-1, 3)
        self._anchor_constraints = [self.chains[i].constraint for i in self._anchored]
        self._piece_bones = np.array([piece.bone for piece in pieces], int)
        self._placed_pieces = np.full((len(pieces), 7), np.nan)  # last placement (t, q_xyzw); NaN: never
        self._placed_anchors = np.full((len(self._anchored), 7), np.nan)
        rest = [bone_frame(link.axis).as_quat() for c in self.chains for link in c.spec.links]  # (x, y, z, w)
        self._rest_frames_inv = quat_conjugate(np.array([(q[3], q[0], q[1], q[2]) for q in rest]).reshape(-1, 4))
        self._exclude_rest_overlaps()
        self._built_state = None  # pybullet state id, saved by the first reset()
        self._pending = None  # (J, 3) the torques set for the next step, not yet stepped
        self._joint_lists = [(c.body, list(range(len(c.spec.joints)))) for c in self.chains]
        self._link_lists = [(c.body, list(range(len(c.spec.links)))) for c in self.chains]
        self._joint_owners = [(c.body, j) for c in self.chains for j in range(len(c.spec.joints))]
        self._child_joints = []  # per joint: (child joint's index, its link frame in this link's frame at rest)
        start = 0
        for c in self.chains:
            frames = [bone_frame(link.axis) for link in c.spec.links]
            for j in range(len(c.spec.links)):
                self._child_joints.append([(start + k, (frames[j].inv() * frames[k]).as_matrix())
                                           for k, p in enumerate(c.spec.link_parents) if p == j])
            start += len(c.spec.links)
        self.dt = float(dt)
        self.springs = Springs([c.spec for c in self.chains], self.dt)
        self._joint_slices = []  # per chain: its joints' rows in the (J, ...) arrays
        for c in self.chains:
            start = self._joint_slices[-1].stop if self._joint_slices else 0
            self._joint_slices.append(slice(start, start + len(c.spec.joints)))
        self._swing_limits = np.array([j.swing_limit for c in self.chains for j in c.spec.joints], np.float64)
        self._twist_limits = np.array([j.twist_limit for c in self.chains for j in c.spec.joints], np.float64)
        # (J,) below this rotation angle a joint is within both limits (less a margin for rounding)
        self._limit_floor = np.minimum(self._swing_limits, self._twist_limits) * (1.0 - 1e-9)
        limits = np.stack([self._limit_floor, self._swing_limits, self._twist_limits])  # (3, J)
        self._kernel_arrays = (limits, self.springs.gains) + self.springs.kernel_arrays
        self._rotation, self._torques = np.zeros((len(limits[0]), 3)), np.zeros((len(limits[0]), 3))  # joint_torques' out

    def _load(self, path: Path, chain: ChainSpec, root_head: np.ndarray, offsets=None) -> int:
        hulls = []
        for j, link in enumerate(chain.links):  # each link's hull beside the URDF (kept on a reload)
            hulls.append(None if link.hull is None else path.with_name(f"{path.stem.split('-')[0]}-l{j}.obj"))
            if hulls[-1] is not None and not hulls[-1].exists():
                hulls[-1].write_text(hull_obj(link))
        path.write_text(chain_urdf(chain, root_head, offsets, [None if h is None else h.name for h in hulls]))
        return self.pb.loadURDF(str(path), basePosition=root_head.tolist(),
                                flags=self.pb.URDF_USE_INERTIA_FROM_FILE | self.pb.URDF_MAINTAIN_LINK_ORDER,
                                physicsClientId=self.client)

    def _touches_body(self, points: np.ndarray, pieces: list[int]) -> bool:
        """Whether the convex hull of world ``points`` (P, 3) comes within the touching margin of
        one of the body pieces ``pieces`` (body ids) where they are now."""
        pb, cid = self.pb, self.client
        shape = pb.createCollisionShape(pb.GEOM_MESH, vertices=points.tolist(), physicsClientId=cid)
        probe = pb.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape, physicsClientId=cid)
        try:
            return any(pb.getClosestPoints(probe, piece, REST_CONTACT_MARGIN, physicsClientId=cid)
                       for piece in pieces)
        finally:
            pb.removeBody(probe, physicsClientId=cid)

    def _root_hulls_clearing_body(self, chain: ChainSpec) -> ChainSpec:
        """``chain`` with each root link's hull kept to its points that lie at least a margin
        outside every body piece but its anchor's at rest, with the smallest margin of
        :data:`CLEARING_MARGINS` whose hull touches none of those pieces.

        A skirt strip reaches into the convex hull of a thigh at rest (the hull is fuller than
        the thigh, and the strip's flare brushes it). Moving the whole shape out leaves the
        strip's vertices centimetres inside the shape, so the thigh pushes the shape and the
        vertices sink into the thigh; dropping the few hull points in the thigh keeps the rest
        of the shape on the strip's vertices. A link that no margin clears keeps its hull (then
        :meth:`_root_offsets_clearing_body` moves it clear).
        """
        if not chain.collision_mask & BODY_GROUP:
            return chain
        others = [(piece, body) for piece, body in zip(self.pieces, self.piece_ids) if piece.bone != chain.anchor_bone]
        if not others:
            return chain
        links = list(chain.links)
        for j, link in enumerate(links):
            if chain.link_parents[j] >= 0 or link.hull is None:
                continue
            world = np.asarray(link.hull, np.float64) + np.asarray(link.head, np.float64)  # (P, 3) at rest
            outside = np.min([np.max((world - self.keypoints[piece.bone]) @ piece.planes[:, :3].T + piece.planes[:, 3],
                                     axis=1) for piece, _ in others], axis=0)  # (P,) lower bound of the distance
            if outside.min() > CLEARING_MARGINS[-1]:
                continue
            for margin in CLEARING_MARGINS:
                kept = hull_points(world[outside > margin])
                if kept is None:
                    break
                if not self._touches_body(kept[0], [body for _, body in others]):
                    links[j] = dataclasses.replace(link, hull=kept[0] - np.asarray(link.head, np.float64))
                    break
        return dataclasses.replace(chain, links=tuple(links))

    def _root_offsets_clearing_body(self, body: int, chain: ChainSpec) -> np.ndarray | None:
        """Collision offsets (L, 3) that move each root link's collision shape out of the body
        pieces it still overlaps at rest (after :meth:`_root_hulls_clearing_body`), other than its
        anchor bone's, along the contact normal by the overlap (plus twice the touching margin);
        None when no root link overlaps one.

        A flared skirt's side strip reaches deep into the thigh's convex piece at rest: ignoring
        that pair lets the thigh sweep through it in a walk, and pushing it out flings the chain.
        Moved just clear, it rests against the thigh and is pushed by it. The deepest overlap
        decides.
        """
        pb, cid = self.pb, self.client
        if not chain.collision_mask & BODY_GROUP:
            return None
        anchor_piece = {piece.bone: b for piece, b in zip(self.pieces, self.piece_ids)}.get(chain.anchor_bone)
        deepest: dict[int, tuple[float, np.ndarray]] = {}  # link -> (depth, world normal)
        for piece_body in self.piece_ids:
            if piece_body == anchor_piece:
                continue
            for point in pb.getClosestPoints(body, piece_body, REST_CONTACT_MARGIN, physicsClientId=cid):
                j = point[3]
                depth = 2 * REST_CONTACT_MARGIN - point[8]
                if j >= 0 and chain.link_parents[j] < 0 and depth > deepest.get(j, (0.0,))[0]:
                    deepest[j] = (depth, np.asarray(point[7], np.float64))  # normal on the piece, toward the link
        if not deepest:
            return None
        offsets = np.zeros((len(chain.links), 3))
        for j, (depth, normal) in deepest.items():
            offsets[j] = bone_frame(chain.links[j].axis).inv().apply(normal * depth)
        return offsets

    def _set_dynamics(self, body: int, chain: ChainSpec) -> None:
        pb, cid = self.pb, self.client
        pb.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0,
                          maxJointVelocity=float(self.sim.max_joint_velocity), physicsClientId=cid)
        pb.setCollisionFilterGroupMask(body, -1, 0, 0, physicsClientId=cid)  # the anchor has no shape anyway
        for j, (link, joint) in enumerate(zip(chain.links, chain.joints)):
            pb.changeDynamics(body, j, linearDamping=link.linear_damping, angularDamping=link.angular_damping,
                              lateralFriction=link.friction, physicsClientId=cid)
            if link.contact_frequency > 0:  # a critically damped contact spring (LinkSpec.contact_frequency)
                w = float(link.contact_frequency)
                pb.changeDynamics(body, j, contactStiffness=link.mass * w * w, contactDamping=2.0 * link.mass * w,
                                  physicsClientId=cid)
            pb.setCollisionFilterGroupMask(body, j, chain.collision_group, chain.collision_mask, physicsClientId=cid)
            pb.setJointMotorControlMultiDof(body, j, pb.POSITION_CONTROL, targetPosition=[0.0, 0.0, 0.0, 1.0],
                                            targetVelocity=[0.0, 0.0, 0.0], positionGain=0.0, velocityGain=0.0,
                                            force=[0.0, 0.0, 0.0], physicsClientId=cid)  # springs: _after_step

    def _exclude_rest_overlaps(self) -> None:
        """Disable collision for pairs that touch in the rest pose where the overlap is the attachment.

        A chain's root link keeps out of every piece it touches at rest (it sits on the body, and
        pushing it out explodes or shoves it into the anchor's piece), every link keeps out of its
        anchor bone's piece, and links of two chains that touch at rest keep out of each other.
        Other overlaps at rest (a long hair hanging through the back) stay in and are pushed out
        while the clip relaxes. A root link's capsule was first moved clear of the other pieces
        it overlapped (:meth:`_root_offsets_clearing_body`), so a thigh at a skirt's top pushes
        that link instead of passing through it; only a root link still touching a piece after
        that (the scalp under a hair root) ignores it.
        """
        pb, cid = self.pb, self.client
        piece_of = {piece.bone: body for piece, body in zip(self.pieces, self.piece_ids)}
        pairs = set()  # (body A, link A, body B, link B) with A a chain
        for n, c in enumerate(self.chains):
            anchor_piece = piece_of.get(c.spec.anchor_bone)
            for body in self.piece_ids:  # one query per pair of bodies; each point names its links
                for point in pb.getClosestPoints(c.body, body, REST_CONTACT_MARGIN, physicsClientId=cid):
                    j = point[3]
                    if j >= 0 and (c.spec.link_parents[j] < 0 or body == anchor_piece):
                        pairs.add((c.body, j, body, -1))
            for other in self.chains[n + 1:]:
                for point in pb.getClosestPoints(c.body, other.body, REST_CONTACT_MARGIN, physicsClientId=cid):
                    if point[3] >= 0 and point[4] >= 0:
                        pairs.add((c.body, point[3], other.body, point[4]))
        for body_a, link_a, body_b, link_b in sorted(pairs):
            pb.setCollisionFilterPair(body_a, body_b, link_a, link_b, 0, physicsClientId=cid)

    def follow(self, poses: np.ndarray, per_frame: int):
        """Follow body poses ``poses`` (S, K, 7), one physics step after each, yielding after every
        ``per_frame`` steps (a clip frame's substeps; :class:`~mimicbench.datagen.apparel.simulate.PhysicsWorld`).

        The pieces' placements and the anchors' pivots and orientations of all S poses are computed
        at once, before the first step; a piece's or an anchor's constraint is changed only
        when its bone moved since the last placement. Moving pieces (``piece_velocity``) are placed
        every step where the step before left them (its pose; the first step's own), with the speed
        that carries them to this step's pose (:func:`piece_velocities`). Only the bones in
        :attr:`driven_bones` are read from ``poses``.
        """
        pb, cid = self.pb, self.client
        poses = np.asarray(poses, np.float64)
        piece_t = poses[:, self._piece_bones, 4:]  # (S, P, 3)
        piece_q = poses[:, self._piece_bones][..., [1, 2, 3, 0]]  # (S, P, 4) x, y, z, w
        q = poses[:, self._anchor_bones, :4]  # (S, A, 4)
        pivots = poses[:, self._anchor_bones, 4:] + _rotate(q.reshape(-1, 4), np.broadcast_to(
            self._anchor_offsets, q.shape[:2] + (3,)).reshape(-1, 3)).reshape(q.shape[:2] + (3,))
        anchor = np.concatenate([pivots, q[..., [1, 2, 3, 0]]], axis=-1)  # (S, A, 7)
        piece = np.concatenate([piece_t, piece_q], axis=-1)  # (S, P, 7)
        before = np.concatenate([self._placed_pieces[None], piece[:-1]])  # (S, P, 7) each piece one step earlier
        piece_moved = np.any(piece != before, axis=-1)
        self._placed_pieces = piece[-1]
        if self._moving_pieces:  # each step starts where the last one ended and carries the piece to its pose
            piece_moved[:] = True
            piece_speed = piece_velocities(piece, before, self.dt, self.sim.gravity).tolist()  # (S, P, 2, 3)
            piece = np.where(np.isnan(before), piece, before)
        anchor_moved = np.any(anchor != np.concatenate([self._placed_anchors[None], anchor[:-1]]), axis=-1)
        self._placed_anchors = anchor[-1]
        piece_at, piece_turn = piece[..., :3].tolist(), piece[..., 3:].tolist()  # per step and piece
        anchor_at, anchor_turn = anchor[..., :3].tolist(), anchor[..., 3:].tolist()  # per step and anchor
        pieces_moved = [[] for _ in range(len(poses))]  # per step: the pieces to move
        for s, i in zip(*(a.tolist() for a in np.nonzero(piece_moved))):
            pieces_moved[s].append(i)
        anchors_moved = [[] for _ in range(len(poses))]
        for s, i in zip(*(a.tolist() for a in np.nonzero(anchor_moved))):
            anchors_moved[s].append(i)
        reset, change, stepper = pb.resetBasePositionAndOrientation, pb.changeConstraint, pb.stepSimulation
        after, piece_ids, constraints = self._after_step, self.piece_ids, self._anchor_constraints
        held, moving, speed = self._piece_constraints, self._moving_pieces, pb.resetBaseVelocity
        for s in range(len(poses)):  # pybullet's client id passed by position where it can be (quicker)
            for i in pieces_moved[s]:
                if held:
                    change(held[i], jointChildPivot=piece_at[s][i], jointChildFrameOrientation=piece_turn[s][i],
                           physicsClientId=cid)
                else:
                    reset(piece_ids[i], piece_at[s][i], piece_turn[s][i], cid)
                    if moving:
                        speed(piece_ids[i], piece_speed[s][i][0], piece_speed[s][i][1], cid)
            for i in anchors_moved[s]:
                change(constraints[i], jointChildPivot=anchor_at[s][i], jointChildFrameOrientation=anchor_turn[s][i],
                       physicsClientId=cid)
            stepper(cid)
            after()
            if (s + 1) % per_frame == 0:
                yield (s + 1) // per_frame - 1

    def reset(self) -> None:
        """Put the world back as it was built (bodies, joints, contacts), ready for another clip.

        pybullet's saveState / restoreState; the spring torques set after the last step are taken
        back (adding their negatives leaves exact zeros), so a clip simulated after a reset gives
        the same bytes as one simulated in a new world (tests/test_apparel_physics.py and
        tests/test_apparel_zoo.py check it). Bullet keeps its overlapping pairs and their contacts
        (with the impulses it warm-starts from) across restoreState: moving pieces (dynamic bodies,
        ``piece_velocity``) join the chains they touch into one solver island, whose contacts' order
        and warm start would then come from the clip before (other bytes in a reused world). So first every body is moved a kilometre from every other and collision
        detection run, which drops every pair; restoreState then puts the bodies back.
        """
        pb, cid = self.pb, self.client
        if self._pending is not None:
            self._apply_torques(-self._pending)
            self._pending = None
        if self._built_state is None:
            self._built_state = pb.saveState(physicsClientId=cid)
        else:
            for k, body in enumerate(self.piece_ids + [c.body for c in self.chains]):
                pb.resetBasePositionAndOrientation(body, [1000.0 * (k + 1), 0.0, 0.0], [0.0, 0.0, 0.0, 1.0],
                                                   physicsClientId=cid)
            pb.performCollisionDetection(physicsClientId=cid)
            pb.restoreState(stateId=self._built_state, physicsClientId=cid)
        self._placed_pieces[:] = np.nan
        self._placed_anchors[:] = np.nan

    def start(self) -> None:
        """Set the springs' torques for the first step from the joints' present state."""
        self._after_step()

    def _after_step(self) -> None:
        """Hold every joint within its limits, then set the springs' torques for the next step.

        Limits: a joint past them is put back onto them and stopped there (inelastic). A joint's
        rotation from rest as a rotation vector r in its frame (Z along the bone): the swing
        (r_x, r_y) is held in the cone |(r_x, r_y)| <= swing limit and the twist to |r_z| <=
        twist limit. Bullet's spherical limit removes only a few percent of the angle past it a
        step, so a chain struck by a fast turn stayed far past it; this removes that angle after
        every step, and the joint's speed further out. A spherical joint's velocity is the child
        link's angular velocity relative to its parent, in the child's frame; the speed taken
        from a joint is given to its child joints (in their frames), so the links below keep
        turning as they did instead of turning back.

        Springs: each joint gets its torque toward rest from :class:`~mimicbench.datagen.apparel.springs.Springs`
        (r, the rotation vector, is the same in the parent's and the child's frame; the velocity is
        in the child's). One read of joint states and one torque call per chain.
        """
        get, cid, lists = self.pb.getJointStatesMultiDof, self.client, self._joint_lists
        if len(lists) == 1:
            states = get(lists[0][0], lists[0][1], cid)
        else:
            states = []
            for body, joints in lists:
                states += get(body, joints, cid)
        if not states:
            return
        try:
            both = np.fromiter(itertools.chain.from_iterable(s[0] + s[1] for s in states), np.float64,
                               7 * len(states)).reshape(-1, 7)  # (J, 7) x, y, z, w, velocity
        except ValueError:  # a joint without a state
            raise RuntimeError(f"pybullet returned no state for some chain joints; expected (4 + 3) "
                               f"numbers for each of {len(states)} spherical joints") from None
        r, tau = self._rotation, self._torques  # (J, 3) rotation vectors (rad), torques (N m), refilled
        over, worst = joint_torques(both, *self._kernel_arrays, r, tau)  # each quaternion turned to w >= 0
        if over:
            velocity = both[:, 4:]  # (J, 3) in each child link's frame
            bend = np.sqrt(np.einsum("ij,ij->i", r[:, :2], r[:, :2]))
            past = np.flatnonzero((bend > self._swing_limits) | (np.abs(r[:, 2]) > self._twist_limits))
            self._project_limits(states, both[:, :4], r, bend, velocity, past)
            tau = self.springs.torques(r, velocity)
        elif worst > 1.0:
            tau = self.springs.within_bounds(r, both[:, 4:], tau)
        self._apply_torques(tau)

    def _apply_torques(self, torques: np.ndarray) -> None:
        """Add ``torques`` (J, 3) N m to the joints for the next step (Bullet sums torques until a step);
        ``torques`` is kept (not copied) until then."""
        pb, cid = self.pb, self.client
        self._pending = torques
        listed = torques.tolist()
        if len(self._joint_lists) == 1:
            body, joints = self._joint_lists[0]
            pb.setJointMotorControlMultiDofArray(body, joints, pb.TORQUE_CONTROL, forces=listed, physicsClientId=cid)
            return
        for (body, joints), rows in zip(self._joint_lists, self._joint_slices):
            pb.setJointMotorControlMultiDofArray(body, joints, pb.TORQUE_CONTROL, forces=listed[rows],
                                                 physicsClientId=cid)

    def _project_limits(self, states, q, r, bend, velocity, over) -> None:
        """Put joints ``over`` (indices, parents first) back onto their limits; ``r`` and
        ``velocity`` (J, 3) are updated in place to what the joints are set to."""
        pb, cid = self.pb, self.client
        turned = Rotation.from_quat(q).as_matrix()  # (J, 3, 3) joint frame -> link frame
        reset = set()
        for j in over.tolist():  # parents before children
            swing, twist = self._swing_limits[j], self._twist_limits[j]
            out = []
            if bend[j] > swing:
                out.append(np.array([r[j, 0], r[j, 1], 0.0]) / bend[j])
                r[j, :2] *= swing / bend[j]
            if abs(r[j, 2]) > twist:
                out.append(np.array([0.0, 0.0, np.sign(r[j, 2])]))
                r[j, 2] = np.sign(r[j, 2]) * twist
            taken = np.zeros(3)
            for direction in out:
                d = turned[j].T @ direction  # in the link's frame
                taken += max(0.0, float(velocity[j] @ d)) * d
            velocity[j] -= taken
            for c, rest_turn in self._child_joints[j]:
                velocity[c] += (rest_turn @ turned[c]).T @ taken
                reset.add(c)
            reset.add(j)
        angle = np.linalg.norm(r, axis=1, keepdims=True)
        quats = np.concatenate([r / np.maximum(angle, 1e-12) * np.sin(angle / 2), np.cos(angle / 2)], axis=1)
        quats[angle[:, 0] <= 1e-12] = [0.0, 0.0, 0.0, 1.0]
        projected = set(over.tolist())
        for j in sorted(reset):
            body, joint = self._joint_owners[j]
            target = quats[j].tolist() if j in projected else list(states[j][0])
            pb.resetJointStateMultiDof(body, joint, targetValue=target, targetVelocity=velocity[j].tolist(),
                                       physicsClientId=cid)

    def place_at(self, pose: np.ndarray) -> None:
        """Teleport the chains and the pieces on constraints rigidly with their bones, before the first step."""
        pb, cid = self.pb, self.client
        for piece, body in zip(self.pieces, self.piece_ids) if self._piece_constraints else ():
            pb.resetBasePositionAndOrientation(body, pose[piece.bone, 4:].tolist(), xyzw(pose[piece.bone, :4]),
                                               physicsClientId=cid)
        for c in self.chains:
            if c.spec.anchor_bone >= 0:
                pb.resetBasePositionAndOrientation(c.body, *self._anchor_placement(c, pose), physicsClientId=cid)

    @staticmethod
    def _anchor_placement(c: ChainBody, pose: np.ndarray) -> tuple[list[float], list[float]]:
        """Where chain ``c``'s base (its root head) sits with its anchor bone at ``pose`` (K, 7): the
        position (3,) m and the orientation (x, y, z, w); an unanchored chain's stays at rest."""
        if c.spec.anchor_bone < 0:
            return c.anchor_offset.tolist(), [0.0, 0.0, 0.0, 1.0]
        q, t = pose[c.spec.anchor_bone, :4], pose[c.spec.anchor_bone, 4:]
        return (t + quat_apply(q, c.anchor_offset)).tolist(), xyzw(q)

    def resettle(self, pose: np.ndarray) -> int:
        """Put each chain with a link faster than :attr:`max_speed` or a non-finite state back at rest
        on its anchor at body pose ``pose`` (K, 7): the base placed rigidly with its anchor bone
        (:meth:`place_at`), every joint at its rest angle, every velocity zero. The spring torques
        set for the next step are taken back (their negatives added) and set again from the new
        state (:meth:`_after_step`). Returns the number of chains put back (multibodies)."""
        pb, cid = self.pb, self.client
        escaped = []
        for c, (body, links) in zip(self.chains, self._link_lists):
            states = pb.getLinkStates(body, links, computeLinkVelocity=1, computeForwardKinematics=1,
                                      physicsClientId=cid)
            numbers = np.array([s[4] + s[5] + s[6] for s in states], np.float64).reshape(-1, 10)
            speeds = np.linalg.norm(numbers[:, 7:], axis=1)
            if not np.isfinite(numbers).all() or (speeds > self.max_speed).any():
                escaped.append(c)
        if not escaped:
            return 0
        for c in escaped:
            pb.resetBasePositionAndOrientation(c.body, *self._anchor_placement(c, pose), physicsClientId=cid)
            pb.resetBaseVelocity(c.body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
            for j in range(len(c.spec.joints)):
                pb.resetJointStateMultiDof(c.body, j, targetValue=[0.0, 0.0, 0.0, 1.0], targetVelocity=[0.0, 0.0, 0.0],
                                           physicsClientId=cid)
        if self._pending is not None:
            self._apply_torques(-self._pending)
        self._after_step()
        return len(escaped)

    def step(self) -> None:
        """One physics step without the limits and springs (Bullet's own dynamics only)."""
        self.pb.stepSimulation(physicsClientId=self.client)
        self._pending = None

    max_speed = property(lambda self: self.sim.max_speed)  # m/s: a faster link is an explosion

    def read(self) -> tuple[tuple[np.ndarray, np.ndarray], float]:
        """Links' world orientations (L, 4) (w, x, y, z), heads (L, 3) m (chain order); fastest speed (m/s)."""
        get, cid = self.pb.getLinkStates, self.client
        states = []
        for body, links in self._link_lists:
            states += get(body, links, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid)
        if not states:
            return (np.zeros((0, 4)), np.zeros((0, 3))), 0.0
        both = np.fromiter(itertools.chain.from_iterable(s[5] + s[4] + s[6] for s in states), np.float64,
                           10 * len(states)).reshape(-1, 10)  # (L, 10) x, y, z, w, head, velocity
        velocity = both[:, 7:]
        return (both[:, [3, 0, 1, 2]], both[:, 4:7]), float(np.sqrt(np.einsum("ij,ij->i", velocity, velocity).max()))

    def clip_out(self, transforms: np.ndarray, states: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """(F, K, 7) float32: ``transforms`` with each link's bone from :meth:`read`'s ``states`` (one a frame):
        its rest-relative rotation (world orientation times the inverse rest one, Z along the bone) and head."""
        out = np.array(transforms, np.float32, copy=True)
        bones = np.array([b for c in self.chains for b in c.spec.bones], int)
        if len(bones):
            out[:, bones, :4] = quat_multiply(np.stack([s[0] for s in states]), self._rest_frames_inv)
            out[:, bones, 4:] = np.stack([s[1] for s in states])
        return out

    def close(self) -> None:
        """Hand the client back: kept for the next world of this process (:data:`_IDLE_CLIENTS`, up
        to :data:`MAX_IDLE_CLIENTS`; a new world empties it first), else disconnected."""
        if self.client is not None:
            if len(_IDLE_CLIENTS) < MAX_IDLE_CLIENTS and self.pb.isConnected(physicsClientId=self.client):
                _IDLE_CLIENTS.append(self.client)
            else:
                self.pb.disconnect(physicsClientId=self.client)
            self.client = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
