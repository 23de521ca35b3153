"""The physics description of a character's apparel: chains of links joined by spherical joints.

This is the stage's internal contract, independent of where the numbers come from: the zoo
defaults (:mod:`mimicbench.datagen.apparel.chains` with :mod:`mimicbench.datagen.apparel.params`) fill it today, and a
PMX file's rigid bodies and joints can fill it per character later (an MMD rigid body is a link,
an MMD joint a :class:`JointSpec`, its collision group and mask the chain's or link's bits).

Geometry is given at rest in the dataset frame: each link's head (the posed keypoint t_k in the
simulation) and its axis; the simulation's link frames have Z along the axis (see
:mod:`mimicbench.datagen.apparel.urdf`). Units: metres, kilograms, radians.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

MAX_MERGED_LINKS = 24  # links of chains joined into one multibody (see merged_by_anchor)


@dataclass(frozen=True)
class LinkSpec:
    """One dynamic link: a capsule along ``axis`` from the bone head, driving bone ``bone``.

    ``head`` (3,) rest position of the bone head (the joint to the parent link), metres;
    ``axis`` (3,) unit direction of the capsule at rest; ``length`` the capsule's cylinder length
    (head to tail), ``radius`` its radius, metres; ``mass`` kg; ``linear_damping`` and
    ``angular_damping`` Bullet's per-link velocity damping (0..1 per second). ``hull`` (P, 3)
    metres relative to ``head`` at rest: the points of the link's convex collision shape (the
    hull of the vertices the bone owns), or None for the capsule. The capsule always gives the
    link's inertia, its axial moment raised to ``axial_share`` of its transverse one
    (:func:`mimicbench.datagen.apparel.urdf.capsule_inertia`; 0: the capsule's own). ``contact_frequency``
    rad/s: above 0 the link's contacts are a critically damped spring of that natural frequency
    on its own mass (Bullet's contact stiffness m w^2 N/m and damping 2 m w N s/m,
    :meth:`mimicbench.datagen.apparel.world.ApparelWorld._set_dynamics`); 0: Bullet's rigid contact.
    """

    bone: int
    head: np.ndarray
    axis: np.ndarray
    length: float
    radius: float
    mass: float
    linear_damping: float = 0.04
    angular_damping: float = 0.1
    friction: float = 0.3
    hull: np.ndarray | None = None
    axial_share: float = 0.0
    contact_frequency: float = 0.0


@dataclass(frozen=True)
class JointSpec:
    """The spherical joint between a link and its parent (the anchor for the chain's first link).

    ``swing_limit`` and ``twist_limit`` (radians) bound the rotation from rest; a spring pulls
    toward rest with ``stiffness`` (0..1, the share of the angle error it takes out in a step),
    ``damping`` (0.., the share of the joint's speed) and at most ``max_torque`` N m per axis
    (:mod:`mimicbench.datagen.apparel.springs`).
    """

    swing_limit: float
    twist_limit: float
    stiffness: float
    damping: float
    max_torque: float


@dataclass(frozen=True)
class ChainSpec:
    """One apparel chain (a tree of apparel bones hanging from one body bone).

    ``links`` in topological order, ``link_parents[i]`` the index of link i's parent link or -1
    for a link on the anchor; ``joints[i]`` joins link i to its parent. ``anchor_bone`` is the
    body bone the chain hangs from (-1: the world). ``collision_group`` and ``collision_mask``
    are bit sets as in MMD (a set mask bit means "collides with that group"); the body is group
    bit 0.
    """

    name: str
    kind: str
    anchor_bone: int
    links: tuple[LinkSpec, ...]
    link_parents: tuple[int, ...]
    joints: tuple[JointSpec, ...]
    collision_group: int = 0b10
    collision_mask: int = 0b01
    meta: dict = field(default_factory=dict)

    @property
    def bones(self) -> list[int]:
        """The bone index of each link, in link order."""
        return [link.bone for link in self.links]


def merged_by_anchor(chains: list[ChainSpec]) -> list[ChainSpec]:
    """``chains`` with those that hang from the same body bone, share collision bits and do not
    collide with one another joined into one chain (one multibody on one anchor, its links in
    the given order), at the place of the first of them.

    Each multibody costs a few pybullet calls every step (its anchor's constraint, a read of its
    joints, its spring torques), so a skirt of eight strips on the hips is one multibody, not
    eight. Links of one multibody never collide, so chains that collide with one another (their
    mask holds their own group) stay apart, as do chains hung from the world. A joined chain
    has at most :data:`MAX_MERGED_LINKS` links (pybullet returns no joint state past about the
    31st spherical joint of a multibody).
    """
    out: list[ChainSpec] = []
    at: dict[tuple, int] = {}
    for chain in chains:
        key = (chain.anchor_bone, chain.collision_group, chain.collision_mask)
        if (chain.anchor_bone < 0 or chain.collision_mask & chain.collision_group or key not in at
                or len(out[at[key]].links) + len(chain.links) > MAX_MERGED_LINKS):
            if chain.anchor_bone >= 0 and not chain.collision_mask & chain.collision_group:
                at[key] = len(out)
            out.append(chain)
            continue
        first = out[at[key]]
        n = len(first.links)
        out[at[key]] = replace(
            first, name=f"{first.name}+{chain.name}", links=first.links + chain.links,
            joints=first.joints + chain.joints,
            link_parents=first.link_parents + tuple(p + n if p >= 0 else -1 for p in chain.link_parents))
    return out
