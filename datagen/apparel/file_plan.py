"""The plan of the Bullet scene of a character's own rigid bodies and joints (tables ``rigid_bodies``
and ``joints``, from an MMD file), instead of the zoo's chain defaults: pure arithmetic, no pybullet
(the world that builds and steps it is :mod:`mimicbench.datagen.apparel.file_physics`).

- **Static** bodies (mode ``static``) are mass-0 bodies with the file's shape (sphere, box,
  capsule along local Y), size, rest position and rotation, moved every substep with their bone
  (kinematic: body = bone transform times the body's rest pose).
- **Dynamic** bodies (``dynamic``, ``dynamic_bone``) are links of multibodies: the joints form a
  graph; a breadth-first search from every static body over joints whose translations are locked
  (then over any joint) gives a tree, and each joint from a static body to a dynamic one roots
  one chain: a multibody loaded from a small URDF whose base (the anchor, no collision, ten
  times the chain's mass) sits at the static body's pose and is carried there by a fixed
  constraint moved every substep (teleporting the base would move the chain rigidly, and it
  would never swing). Each link is one body with the file's shape, mass (inertia of that
  shape), friction and restitution.
- **Joints**: pybullet does not expose Bullet's generic 6-DOF spring constraint, so each tree
  joint is a spherical joint with Bullet's spherical limit (an ellipse cone of two swing ranges
  and a twist range, hard limits), or a fixed joint when all three rotation ranges are locked.
  The joint frame's Y (the twist axis of MMD's capsules) becomes the limit's twist axis and Z, X
  its swing axes; the cone is centred on the midpoints of the file's rotation ranges (so an
  asymmetric range such as a skirt's [-3, 60] degrees stays asymmetric) and its half-widths are
  the half-ranges; a free axis (lower above upper, Bullet's convention) gets a half-width of
  3.1 rad. Tree joints lock translation (MMD's joints almost always do; a translation range is
  noted). A joint that would close a loop is a point-to-point constraint when at least two of
  its translation axes are locked (the third is then locked too: a ring of cloak panels whose
  joints let them slide along one axis stays a ring) and its bodies are not joined already;
  otherwise it is dropped and counted with the reason.
- **Springs** (rotation stiffness per axis, MMD's units: torque per radian, times
  ``metres_per_unit`` squared for metres) become the joint's position motor toward the rest pose.
  Bullet's motor drives the joint's velocity toward ``gain * error / dt`` with a torque limit per
  axis: the gain is ``omega dt`` with ``omega = sqrt(k / I)`` (k the mean of the non-zero
  stiffnesses, I the link's moment of inertia about the joint), so the joint returns to rest on
  the spring's own time scale; each axis's torque limit is its stiffness times the limit's
  half-width (the largest torque that spring gives inside its range), so an axis without a spring
  has no motor. Unlike a spring, the motor holds a load up to that torque without sagging, and
  it does not overshoot (MMD's joints have no damping; its bodies' damping does that work).
  Translation springs are not simulated (tree joints lock translation).
- **Collision filters**: a body's group is the bit ``1 << collision_group``; its mask is the
  stored 16 bits as they are. MMD's editors show the field as "non-collision groups" (checked =
  do not collide), but the file stores the complement: a set bit means "collides with that
  group" (mmd_tools reads it as ``non_collision[i] = not mask & (1 << i)``; Gene's static body
  bodies store 0xFFFF, its cloak weights 0x0000). Two bodies collide when each one's group bit is
  in the other's mask (:func:`collision_filter`; pybullet's default filter is the OR of the two
  tests, so the world sets ``collisionFilterMode=0``, the AND). Links of one chain do not collide with each
  other (pybullet's multibody default).
- **Damping**: MMD's per-body damping d scales velocities by ``(1 - d)`` per second (Bullet's
  rigid bodies); Bullet's multibodies have one damping per multibody, applied as a force
  ``-m v (c + c |v|)``: each chain gets ``c = -ln(1 - d)`` averaged over its bodies by mass, which
  matches MMD's decay rate at low speed.
- **Modes**: a ``dynamic`` body's bone takes the body's rotation and position; a
  ``dynamic_bone`` body's bone takes the body's rotation and its position from its parent bone
  (forward kinematics over the simulated parents, as MMD's "physics + bone position"). Bones
  below simulated bones that have no body move rigidly with their parent. Every other bone keeps
  the clip's transforms exactly. A dynamic body that no joint ties to a static body stays
  kinematic (counted).
- **Time**: fixed steps of ``1 / (clip fps * substeps)``; gravity 9.8 m/s^2 along -Y in metres
  (MMD players use 9.8 x 10 units/s^2, which is 7.84 m/s^2 at 0.08 m per unit).
"""
from __future__ import annotations

import math
import warnings
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from mimicbench.geometry.quaternion import quat_conjugate, quat_multiply
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

LOCKED = 1e-4  # a range narrower than this (metres or radians) is locked
FREE_HALF_WIDTH = 3.1  # radians: the cone half-width of a free axis
MIN_HALF_WIDTH = 1e-3  # radians: the narrowest cone Bullet gets (zero widths jitter)
ANCHOR_MASS_SHARE = 10.0
LIMIT_IMPULSE = 1000.0
MIN_MASS = 1e-3
# Bullet's frame of a joint from the MMD joint frame: its X, Y, Z are the joint's z, x, y
# (columns), so the twist (Bullet's Z) is the joint's Y, the axis of MMD's capsules
JOINT_TO_BULLET = Rotation.from_matrix(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
CAPSULE_Z_TO_Y = Rotation.from_rotvec([-np.pi / 2, 0.0, 0.0])  # URDF capsules lie along Z, MMD's along Y


def collision_filter(group: int, mask: int) -> tuple[int, int]:
    """pybullet's (group bits, mask bits) of an MMD body: ``1 << group`` and the stored 16-bit mask
    (a set bit collides with that group; see the module docstring)."""
    if not 0 <= int(group) <= 15:
        raise ValueError(f"collision group {group}: expected 0..15")
    return 1 << int(group), int(mask) & 0xFFFF


def wxyz_rotation(q) -> Rotation:
    q = np.asarray(q, np.float64)
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


def rotation_xyzw(r: Rotation) -> list[float]:
    return [float(x) for x in r.as_quat()]


def _locked(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return (lo <= hi) & (hi - lo < LOCKED)


@dataclass
class ChainPlan:
    """One multibody: its anchor (a static body), its links (dynamic bodies in tree order, parents
    first), each link's parent link (-1: the anchor), the joint that ties it there, and whether
    that joint runs from the link to its parent (B to A) rather than A to B."""

    anchor: int
    links: list[int] = field(default_factory=list)
    link_parents: list[int] = field(default_factory=list)
    joints: list[int] = field(default_factory=list)
    reversed: list[bool] = field(default_factory=list)


@dataclass
class ScenePlan:
    """How a character's bodies and joints become the Bullet scene (see the module docstring)."""

    chains: list[ChainPlan]
    loops: list[int]  # joints made point-to-point constraints
    dropped: dict[int, str]  # joint index -> why it is not simulated
    unanchored: list[int]  # dynamic bodies no joint ties to a static body (kept kinematic)
    notes: list[str] = field(default_factory=list)


def plan_scene(bodies: list[RigidBodyRecord], joints: list[JointRecord]) -> ScenePlan:
    """Chains, loop constraints and dropped joints of ``bodies`` and ``joints`` (file order).

    Raises:
        ValueError: a joint names a body that does not exist.
    """
    n = len(bodies)
    static = [b.mode == "static" for b in bodies]
    edges: dict[int, list[tuple[int, int]]] = {i: [] for i in range(n)}
    for j, jr in enumerate(joints):
        a, b = int(jr.body_a), int(jr.body_b)
        if not (0 <= a < n and 0 <= b < n):
            raise ValueError(f"joint {j} ({jr.name}): bodies {a}, {b}; expected indices below {n}")
        if a != b:
            edges[a].append((j, b))
            edges[b].append((j, a))
    locked_t = [bool(_locked(jr.translation_min, jr.translation_max).all()) for jr in joints]
    parent_of: dict[int, tuple[int, int]] = {}  # dynamic body -> (parent body, joint)
    reached = [static[i] for i in range(n)]
    used: set[int] = set()
    for only_locked in (True, False):
        queue = deque(i for i in range(n) if reached[i])
        while queue:
            i = queue.popleft()
            for j, other in edges[i]:
                if reached[other] or static[other] or (only_locked and not locked_t[j]):
                    continue
                reached[other] = True
                parent_of[other] = (i, j)
                used.add(j)
                queue.append(other)
    chains: dict[int, ChainPlan] = {}
    chain_of: dict[int, int] = {}
    order = sorted(parent_of, key=lambda b: _depth(b, parent_of))
    for b in order:
        p, j = parent_of[b]
        if static[p]:
            chain_of[b] = j
            chains[j] = ChainPlan(anchor=p)
        else:
            chain_of[b] = chain_of[p]
        c = chains[chain_of[b]]
        c.link_parents.append(-1 if static[p] else c.links.index(p))
        c.links.append(b)
        c.joints.append(j)
        c.reversed.append(int(joints[j].body_a) == b)
    joined = {frozenset((int(joints[j].body_a), int(joints[j].body_b))) for j in used}
    loops, dropped = [], {}
    for j, jr in enumerate(joints):
        if j in used:
            continue
        a, b = int(jr.body_a), int(jr.body_b)
        if a == b:
            dropped[j] = "joins a body to itself"
        elif static[a] and static[b]:
            dropped[j] = "joins two static bodies"
        elif not (a in parent_of or static[a]) or not (b in parent_of or static[b]):
            dropped[j] = "a body of it is not tied to a static body"
        elif frozenset((a, b)) in joined:
            dropped[j] = "its bodies are joined already"
        elif _locked(jr.translation_min, jr.translation_max).sum() < 2:
            dropped[j] = "closes a loop with two or three free translation axes"
        else:
            loops.append(j)
            joined.add(frozenset((a, b)))
    notes = [f"joint {j} ({joints[j].name}): translation range not simulated (tree joints lock translation)"
             for j in sorted(used) if not locked_t[j]]
    unanchored = [i for i in range(n) if not static[i] and i not in parent_of]
    return ScenePlan([chains[j] for j in sorted(chains, key=lambda j: chains[j].links[0])], loops, dropped,
                     unanchored, notes)


def _depth(b: int, parent_of: dict) -> tuple[int, int]:
    d, x = 0, b
    while x in parent_of:
        x = parent_of[x][0]
        d += 1
    return d, b


def joint_bounds(jr: JointRecord, reverse: bool) -> tuple[np.ndarray, np.ndarray]:
    """A joint's rotation range (lower (3,), upper (3,)) rad on the MMD joint's axes, of its child
    relative to its parent, the file's convention kept (lower above upper: a free axis).
    ``reverse``: the child is body A, so the child-relative rotation is the inverse and every
    range is negated."""
    lo, hi = np.asarray(jr.rotation_min, np.float64), np.asarray(jr.rotation_max, np.float64)
    return (-hi, -lo) if reverse else (lo, hi)


def intersect_bounds(first: tuple[np.ndarray, np.ndarray], second: tuple[np.ndarray, np.ndarray]
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The range both of two joints between the same bodies allow (MMD's Bullet enforces both):
    per axis the overlap of the two ranges, a free axis (lower above upper) taking the other's
    range; an axis whose ranges do not overlap keeps ``first``'s."""
    (lo1, hi1), (lo2, hi2) = first, second
    free1, free2 = lo1 > hi1, lo2 > hi2
    lo, hi = np.maximum(lo1, lo2), np.minimum(hi1, hi2)
    keep = free2 | (lo > hi)  # the second is free, or the two do not overlap
    return np.where(free1, lo2, np.where(keep, lo1, lo)), np.where(free1, hi2, np.where(keep, hi1, hi))


def same_frame(first: JointRecord, second: JointRecord, tol: float = 1e-4) -> bool:
    """Whether two joints' ranges are on the same axes (equal joint rotations, radians): only then
    can :func:`intersect_bounds` overlap them axis by axis."""
    return bool(np.allclose(np.asarray(first.rotation, np.float64), np.asarray(second.rotation, np.float64), atol=tol))


def cone_of(jr: JointRecord, reverse: bool, bounds: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[Rotation, np.ndarray, bool]:
    """The spherical limit of a joint in Bullet's joint frame.

    Returns (C, (swing X, swing Y, twist) half-widths in radians, locked): C is the rotation from
    the joint's rest frame to the cone's centre (Euler XYZ of the range midpoints, in Bullet's
    frame); ``locked`` when all three ranges are locked (a fixed joint). ``reverse``: the child is
    body A, so the child-relative rotation is the inverse and every range is negated.
    ``bounds``: the child-relative range to use instead of the joint's own (:func:`joint_bounds`).
    """
    lo, hi = joint_bounds(jr, reverse) if bounds is None else bounds
    free = lo > hi
    mid = np.where(free, 0.0, 0.5 * (lo + hi))
    half = np.where(free, FREE_HALF_WIDTH, np.minimum(0.5 * (hi - lo), FREE_HALF_WIDTH))
    locked = bool(_locked(lo, hi).all())
    centre = JOINT_TO_BULLET.inv() * Rotation.from_euler("xyz", mid) * JOINT_TO_BULLET
    # joint axes (x, y, z) are Bullet's (Y, Z, X): swing X <- z, swing Y <- x, twist Z <- y
    widths = np.maximum(np.array([half[2], half[0], half[1]]), MIN_HALF_WIDTH)
    return centre, widths, locked


def _inertia(body: RigidBodyRecord, mass: float) -> np.ndarray:
    """(3,) principal moments in the body's frame (capsule along Y as a cylinder of full length)."""
    s = np.asarray(body.size, np.float64)
    if body.shape == "sphere":
        return np.full(3, 0.4 * mass * s[0] ** 2)
    if body.shape == "box":
        a, b, c = 2 * s
        return mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    r, h = s[0], s[1] + 2 * s[0]
    t = mass * (3 * r * r + h * h) / 12.0
    return np.array([t, mass * r * r / 2.0, t])


def _geometry(body: RigidBodyRecord) -> str:
    s = np.asarray(body.size, np.float64)
    if body.shape == "sphere":
        return f'<sphere radius="{_f(max(s[0], 1e-4))}"/>'
    if body.shape == "box":
        return f'<box size="{_vec(np.maximum(2 * s, 1e-4))}"/>'
    return f'<capsule radius="{_f(max(s[0], 1e-4))}" length="{_f(max(s[1], 1e-4))}"/>'


def _f(x: float) -> str:
    return format(float(x), ".9g")


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _origin(pos, rot: Rotation) -> str:
    with warnings.catch_warnings():  # a quarter turn about Y is a gimbal lock; the angles stay exact
        warnings.simplefilter("ignore", UserWarning)
        rpy = rot.as_euler("xyz")  # URDF rpy: fixed-axis X, Y, Z
    return f'<origin xyz="{_vec(pos)}" rpy="{_vec(rpy)}"/>'


@dataclass
class ChainBuild:
    """A chain's URDF and the rest data the world needs: link frames (world, at rest), the rest
    joint rotations (x, y, z, w) the motors hold, per-link motor gains and torque limits."""

    urdf: str
    anchor_pos: np.ndarray
    anchor_rot: Rotation
    link_pos: np.ndarray  # (L, 3)
    link_rot: list[Rotation]
    rest_q: list[list[float]]
    body_rot: list[Rotation]  # each body's rotation in its link frame
    fixed: list[bool]
    gains: list[tuple[float, list[float]]]  # (position gain, torque limits (3,) N m); zeros: no motor
    mass: float
    damping: tuple[float, float]  # Bullet multibody (linear, angular)


def build_chain(plan: ChainPlan, bodies: list[RigidBodyRecord], joints: list[JointRecord], dt: float,
                metres_per_unit: float, duplicate_ranges: bool = False) -> ChainBuild:
    """The URDF of one chain (see the module docstring); ``dt`` the physics step (seconds).
    ``duplicate_ranges``: a joint's range is the overlap of its own and those of the other joints
    between the same two bodies on the same axes (:func:`same_frame`; dropped from the scene as
    duplicates, :func:`plan_scene`; MMD's Bullet enforces every one of them, :func:`intersect_bounds`);
    False: the tree joint's own range."""
    anchor = bodies[plan.anchor]
    a_pos, a_rot = np.asarray(anchor.position, np.float64), wxyz_rotation(anchor.rotation)
    masses = [max(float(bodies[b].mass), MIN_MASS) for b in plan.links]
    total = sum(masses)
    a_mass = ANCHOR_MASS_SHARE * total
    reach = max(np.linalg.norm(np.asarray(bodies[b].position) - a_pos) for b in plan.links) + 1e-3
    a_i = 0.4 * a_mass * reach ** 2
    out = [f'<robot name="chain{plan.anchor}">',
           f'<link name="anchor"><inertial><origin xyz="0 0 0"/><mass value="{_f(a_mass)}"/>'
           f'<inertia ixx="{_f(a_i)}" iyy="{_f(a_i)}" izz="{_f(a_i)}" ixy="0" ixz="0" iyz="0"/></inertial></link>']
    link_pos, link_rot, rest_q, fixed, gains, body_rot = [], [], [], [], [], []
    for i, (b, parent, j, rev) in enumerate(zip(plan.links, plan.link_parents, plan.joints, plan.reversed)):
        body, jr = bodies[b], joints[j]
        pos = np.asarray(jr.position, np.float64)
        rot = wxyz_rotation(jr.rotation) * JOINT_TO_BULLET  # link frame = Bullet's joint frame at rest
        bounds = joint_bounds(jr, rev)
        if duplicate_ranges:
            pair = {b, plan.anchor if parent < 0 else plan.links[parent]}
            for k, other in enumerate(joints):
                if k != j and {int(other.body_a), int(other.body_b)} == pair and same_frame(jr, other):
                    bounds = intersect_bounds(bounds, joint_bounds(other, int(other.body_a) == b))
        centre, widths, locked = cone_of(jr, rev, bounds)
        p_pos, p_rot = (a_pos, a_rot) if parent < 0 else (link_pos[parent], link_rot[parent])
        origin_rot = p_rot.inv() * rot * centre  # the joint's zero: the cone's centre
        origin_pos = p_rot.inv().apply(pos - p_pos)
        b_pos, b_rot = np.asarray(body.position, np.float64), wxyz_rotation(body.rotation)
        rel_pos, rel_rot = rot.inv().apply(b_pos - pos), rot.inv() * b_rot
        inertia = _inertia(body, masses[i])
        # Bullet turns a spherical joint in its link's inertial frame: that frame must not be rotated
        # against the link frame, so the inertia is the diagonal of the tensor in the link frame
        link_inertia = np.diag(rel_rot.as_matrix() @ np.diag(inertia) @ rel_rot.as_matrix().T)
        geom_rot = rel_rot * CAPSULE_Z_TO_Y if body.shape == "capsule" else rel_rot
        out.append(f'<link name="l{i}"><inertial><origin xyz="{_vec(rel_pos)}"/><mass value="{_f(masses[i])}"/>'
                   f'<inertia ixx="{_f(link_inertia[0])}" iyy="{_f(link_inertia[1])}" izz="{_f(link_inertia[2])}" '
                   f'ixy="0" ixz="0" iyz="0"/></inertial><collision>{_origin(rel_pos, geom_rot)}'
                   f'<geometry>{_geometry(body)}</geometry></collision></link>')
        parent_name = "anchor" if parent < 0 else f"l{parent}"
        if locked:
            origin_rot = p_rot.inv() * rot
            out.append(f'<joint name="j{i}" type="fixed"><parent link="{parent_name}"/><child link="l{i}"/>'
                       f'{_origin(origin_pos, origin_rot)}</joint>')
        else:
            out.append(f'<joint name="j{i}" type="spherical"><parent link="{parent_name}"/><child link="l{i}"/>'
                       f'{_origin(origin_pos, origin_rot)}<axis xyz="0 0 1"/><limit lower="{_f(widths[0])}" '
                       f'upper="{_f(widths[1])}" twist="{_f(widths[2])}" effort="{_f(LIMIT_IMPULSE)}" '
                       f'velocity="100"/></joint>')
        link_pos.append(pos)
        link_rot.append(rot)
        rest_q.append(rotation_xyzw(centre.inv()))
        body_rot.append(rel_rot)
        fixed.append(locked)
        k = np.maximum(np.asarray(jr.spring_rotation, np.float64), 0.0)[[2, 0, 1]] * metres_per_unit ** 2
        if locked or not (k > 0).any():
            gains.append((0.0, [0.0, 0.0, 0.0]))
        else:
            arm = np.linalg.norm(b_pos - pos)
            moment = masses[i] * arm ** 2 + float(np.mean(inertia))
            omega = math.sqrt(float(k[k > 0].mean()) / moment)
            gains.append((min(1.0, omega * dt), (k * widths).tolist()))
    out.append("</robot>")
    rates = [(-math.log(1.0 - min(float(bodies[b].linear_damping), 0.999)),
              -math.log(1.0 - min(float(bodies[b].angular_damping), 0.999))) for b in plan.links]
    damping = tuple(float(np.average([r[i] for r in rates], weights=masses)) for i in range(2))
    return ChainBuild("\n".join(out) + "\n", a_pos, a_rot, np.array(link_pos).reshape(-1, 3), link_rot, rest_q,
                      body_rot, fixed, gains, a_mass, damping)


def bones_from_bodies(bodies: list[RigidBodyRecord], parents: np.ndarray, keypoints: np.ndarray, clip_pose: np.ndarray,
                      positions: dict, rotations: dict, apparel: np.ndarray) -> np.ndarray:
    """(K, 7) float64: ``clip_pose`` (K, 7) with the simulated bones replaced (module docstring).

    A bone of a dynamic body takes the body's rotation relative to its rest rotation; its head
    follows the body (``dynamic``) or its parent bone (``dynamic_bone``); apparel bones below
    simulated ones without a body of their own move rigidly with their parent (its clip-local
    transform kept).
    """
    out = np.array(clip_pose, np.float64, copy=True)
    driver: dict[int, int] = {}
    for b in positions:
        driver.setdefault(int(bodies[b].bone), b)
    driver.pop(-1, None)
    changed = np.zeros(len(out), bool)
    for k in range(len(out)):  # parents come first
        p = int(parents[k])
        if k in driver:
            b = driver[k]
            body = bodies[b]
            q = quat_multiply(rotations[b], quat_conjugate(np.asarray(body.rotation, np.float64)))
            out[k, :4] = q
            if body.mode == "dynamic" or p < 0:
                out[k, 4:] = positions[b] + wxyz_rotation(q).apply(keypoints[k] - np.asarray(body.position))
            else:
                out[k, 4:] = _follow(out[p], clip_pose[p], clip_pose[k])[4:]
            changed[k] = True
        elif p >= 0 and changed[p] and apparel[k]:
            out[k] = _follow(out[p], clip_pose[p], clip_pose[k])
            changed[k] = True
    return out


def _follow(parent_new: np.ndarray, parent_clip: np.ndarray, child_clip: np.ndarray) -> np.ndarray:
    """A child's (7,) transform carried rigidly by its parent's change from clip to new."""
    delta = quat_multiply(parent_new[:4], quat_conjugate(parent_clip[:4]))
    t = parent_new[4:] + wxyz_rotation(delta).apply(child_clip[4:] - parent_clip[4:])
    return np.concatenate([quat_multiply(delta, child_clip[:4]), t])
