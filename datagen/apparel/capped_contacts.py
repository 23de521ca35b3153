"""Contacts between a file world's bone-following bodies and its chains' links, one closest point a
pair, with the force capped per kilogram of the link.

Each (bone-following body, chain link) pair whose collision groups and masks let them touch is
taken out of Bullet's contacts (:meth:`CappedContacts.attach`); before each step, the pairs whose
bounding spheres overlap are asked for their deepest point (pybullet's ``getClosestPoints``, one
GJK/EPA query a pair, so the contact does not gain and lose manifold points) and each touching pair
pushes the link with :func:`contact_force`, an external force at that point:

- a critically damped spring of frequency ``w`` on the link's mass ``m`` (stiffness ``m w^2``,
  damping ``2 m w`` on the speed into the body, the body's own speed from its bone's motion taken
  off, so a limb carrying a link does not drag it), never pulling;
- Coulomb friction with coefficient ``mu``, viscous below sliding (at most ``2 m w`` times the
  tangential speed), so it stops a slide without reversing it;
- the normal force capped at ``m * cap`` (and the friction at ``mu`` times that): a link squeezed
  between two bodies that overlap each other (hair between a raised arm and the head) yields into
  them instead of being thrown out when a contact changes.

Bullet's contacts between chains are unchanged. The force is explicit (from the state before the
step): at 240 Hz and 75 rad/s the spring's ``w dt`` is 0.31 and the damping's ``2 w dt`` 0.63 on
the link's mass; a point far from a long link's centre shows less mass (a thin rod's end a
quarter), where the damping may over-correct within a step, and the cap bounds the force either way.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.rigid_body import RigidBodyRecord

REACH_SLACK = 0.01  # metres added to two bounding spheres' radii before a pair is asked for its point


def contact_force(depth: float, normal: np.ndarray, relative_velocity: np.ndarray, mass: float, frequency: float,
                  friction: float, cap: float) -> np.ndarray:
    """(3,) newtons on a link sunk ``depth`` metres (> 0) into a body along ``normal`` (3,), the unit
    vector out of the body towards the link, moving at ``relative_velocity`` (3,) m/s relative to the
    body's surface there; ``mass`` kg, ``frequency`` rad/s, ``friction`` Coulomb's coefficient,
    ``cap`` m/s^2 (0: none). Zero when the spring and damping together would pull."""
    normal = np.asarray(normal, np.float64)
    velocity = np.asarray(relative_velocity, np.float64)
    into = -float(velocity @ normal)  # m/s, positive when the link moves deeper
    push = mass * frequency * frequency * depth + 2.0 * mass * frequency * into
    if push <= 0.0:
        return np.zeros(3)
    if cap > 0.0:
        push = min(push, mass * cap)
    force = push * normal
    sliding = velocity + into * normal  # the tangential part
    speed = float(np.linalg.norm(sliding))
    if friction > 0.0 and speed > 1e-12:
        force -= min(friction * push, 2.0 * mass * frequency * speed) * sliding / speed
    return force


def bounding_radius(body: RigidBodyRecord) -> float:
    """Metres from a body's centre to the farthest point of its shape."""
    size = np.asarray(body.size, np.float64)
    if body.shape == "sphere":
        return float(size[0])
    if body.shape == "box":
        return float(np.linalg.norm(size))
    if body.shape == "capsule":
        return float(size[0] + size[1] / 2.0)
    raise ValueError(f"rigid body {body.name}: shape {body.shape!r}; expected sphere, box or capsule")


def touches(a: RigidBodyRecord, b: RigidBodyRecord) -> bool:
    """Whether MMD's collision groups and masks let two bodies touch (each body's mask has the
    other's group bit)."""
    return bool((int(a.collision_mask) >> int(b.collision_group)) & 1 and (int(b.collision_mask) >> int(a.collision_group)) & 1)


@dataclass(frozen=True)
class ContactPair:
    """One bone-following body and one chain link that may touch."""

    static_row: int  # row of the body among the world's bone-following bodies
    chain: int  # index of the link's chain
    link: int  # link index in the chain's multibody
    mass: float  # kg, the link's
    friction: float  # Coulomb coefficient: the geometric mean of the two bodies'
    reach: float  # metres: the two bounding radii and REACH_SLACK


class CappedContacts:
    """The capped contacts of one pybullet world (see the module docstring).

    Args:
        pb, client: pybullet and the world's client id.
        pairs: the pairs that may touch (:meth:`attach` builds them).
        link_counts: {chain index: links in its multibody} for the chains of ``pairs``.
        frequency: rad/s, the contact spring's. cap: m/s^2, the normal force's limit per kilogram
            of the link (0: none).
    """

    def __init__(self, pb, client: int, pairs: list[ContactPair], link_counts: dict[int, int], frequency: float,
                 cap: float):
        self.pb, self.client = pb, client
        self.link_counts = link_counts
        self.pairs, self.frequency, self.cap = pairs, float(frequency), float(cap)
        self._rows = np.array([(p.static_row, p.chain, p.link) for p in pairs], int).reshape(-1, 3)
        self._reach = np.array([p.reach for p in pairs], np.float64)

    @classmethod
    def attach(cls, pb, client: int, bodies: list[RigidBodyRecord], static: list[int], static_ids: list[int],
               chains: list[tuple[list[int], int]], frequency: float, cap: float) -> CappedContacts:
        """Take every touching (bone-following body, chain link) pair out of Bullet's contacts and
        return the contacts that replace them. ``static``: the bone-following bodies' record indices,
        ``static_ids`` their pybullet ids; ``chains``: each chain's link records (record indices in link
        order) and multibody id."""
        pairs = []
        for c, (links, multibody) in enumerate(chains):
            for li, b in enumerate(links):
                mass = float(pb.getDynamicsInfo(multibody, li, physicsClientId=client)[0])
                for row, s in enumerate(static):
                    if not touches(bodies[s], bodies[b]):
                        continue
                    pb.setCollisionFilterPair(static_ids[row], multibody, -1, li, 0, physicsClientId=client)
                    pairs.append(ContactPair(row, c, li, mass,
                                             float(np.sqrt(max(bodies[s].friction, 0.0) * max(bodies[b].friction, 0.0))),
                                             bounding_radius(bodies[s]) + bounding_radius(bodies[b]) + REACH_SLACK))
        counts = {p.chain: len(chains[p.chain][0]) for p in pairs}
        return cls(pb, client, pairs, counts, frequency, cap)

    def apply(self, multibodies: list[int], static_ids: list[int], static_positions: np.ndarray,
              static_velocities: np.ndarray) -> int:
        """Push every touching pair's link for the next step. ``multibodies``: each chain's id;
        ``static_positions`` (S, 3) metres and ``static_velocities`` (S, 2, 3) (linear m/s, angular
        rad/s, world frame) the bone-following bodies' centres and speeds this step. Returns the
        number of pairs that pushed."""
        pb, cid = self.pb, self.client
        if not self.pairs:
            return 0
        states = {}
        centres = {}
        for c, count in self.link_counts.items():
            states[c] = pb.getLinkStates(multibodies[c], list(range(count)), computeLinkVelocity=1, physicsClientId=cid)
            centres[c] = np.array([s[0] for s in states[c]], np.float64)
        link_centres = np.array([centres[c][li] for _, c, li in self._rows])
        near = np.linalg.norm(static_positions[self._rows[:, 0]] - link_centres, axis=1) < self._reach
        pushed = 0
        for k in np.nonzero(near)[0]:
            pair = self.pairs[k]
            mb = multibodies[pair.chain]
            points = pb.getClosestPoints(static_ids[pair.static_row], mb, 0.0, -1, pair.link, physicsClientId=cid)
            if not points:
                continue
            deepest = min(points, key=lambda p: p[8])
            if deepest[8] >= 0.0:
                continue
            at = np.asarray(deepest[6], np.float64)  # on the link
            state = states[pair.chain][pair.link]
            link_velocity = np.asarray(state[6]) + np.cross(state[7], at - np.asarray(state[0]))
            body_velocity = static_velocities[pair.static_row]
            surface_velocity = body_velocity[0] + np.cross(body_velocity[1], at - static_positions[pair.static_row])
            force = contact_force(-deepest[8], -np.asarray(deepest[7], np.float64), link_velocity - surface_velocity,
                                  pair.mass, self.frequency, pair.friction, self.cap)
            if force.any():
                pb.applyExternalForce(mb, pair.link, force.tolist(), at.tolist(), pb.WORLD_FRAME, physicsClientId=cid)
                pushed += 1
        return pushed
