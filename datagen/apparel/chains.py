"""Apparel chains of a character, with links sized from bone lengths and the vertices they drive.

A chain is a tree of apparel bones whose root's parent is a body bone (its anchor). Each apparel
bone is one link: a capsule from its head toward its first apparel child's head (a leaf bone
continues its parent's direction, as far as its own vertices reach), with a radius from the
distance of its driven vertices to that segment, which gives the link's inertia; the link
collides as the convex hull of the vertices the bone owns (a skirt strip is flat and wide: a
capsule round it is far thicker than the strip and reaches into the hips and thighs), or as the
capsule where those vertices span no volume. Joint and link physics come from the chain's kind
(:mod:`mimicbench.datagen.apparel.params`).
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.apparel.body_shapes import hull_points
from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
from mimicbench.datagen.apparel.params import ApparelParams
from mimicbench.datagen.apparel.selection import bone_kind

MAX_LINK_HULL_POINTS = 48  # a link's collision hull: fewer points than a body piece's, many more links


def chain_roots(parents: np.ndarray, apparel: np.ndarray) -> list[int]:
    """Apparel bones whose parent is a body bone or none, in bone order."""
    return [k for k in range(len(parents)) if apparel[k] and (parents[k] < 0 or not apparel[parents[k]])]


def _subtree(root: int, parents: np.ndarray, apparel: np.ndarray) -> list[int]:
    members = {root}
    for k in range(root + 1, len(parents)):  # parents[k] < k: one pass in bone order
        if apparel[k] and parents[k] in members:
            members.add(k)
    return sorted(members)


def _segment_distance(points: np.ndarray, head: np.ndarray, axis: np.ndarray, length: float) -> np.ndarray:
    s = np.clip((points - head) @ axis, 0.0, length)
    return np.linalg.norm(points - head - s[:, None] * axis, axis=1)


def _link_geometry(k: int, bones: list[int], parents, keypoints, vertices, owner, height: float):
    """(axis, length, spread, hull) of bone k's link: the capsule's axis and length, spread = the
    75th percentile distance of its vertices from the segment, and the points (P, 3) of the hull
    of its vertices relative to its head (None when they span no volume)."""
    head = keypoints[k]
    children = [c for c in bones if parents[c] == k]
    own = vertices[owner == k]
    if children:
        tail = keypoints[children[0]]
        axis = tail - head
        length = float(np.linalg.norm(axis))
    else:
        p = parents[k]
        axis = head - keypoints[p] if p >= 0 else (own.mean(0) - head if len(own) else np.array([0.0, -1.0, 0.0]))
        axis_n = axis / max(np.linalg.norm(axis), 1e-9)
        reach = float(((own - head) @ axis_n).max()) if len(own) else 0.0
        length = reach if reach > 0 else float(np.linalg.norm(axis))
    if np.linalg.norm(axis) < 1e-9 or length < 1e-4:
        axis, length = np.array([0.0, -1.0, 0.0]), 0.02 * height
    axis = axis / np.linalg.norm(axis)
    spread = float(np.percentile(_segment_distance(own, head, axis, length), 75)) if len(own) else 0.01 * height
    found = hull_points(own - head, 0.002 * height, MAX_LINK_HULL_POINTS)
    return axis, length, max(spread, 0.002 * height), (None if found is None else found[0])


def shell(hull: np.ndarray | None, axis: np.ndarray, length: float, thickness: float) -> np.ndarray | None:
    """``hull`` (P, 3) points relative to a link's head, each moved ``thickness`` metres further from
    the link's bone (the segment from the head along unit ``axis`` for ``length``); None stays None."""
    if hull is None or thickness <= 0:
        return hull
    points = np.asarray(hull, np.float64)
    along = np.clip(points @ axis, 0.0, length)
    out = points - along[:, None] * axis  # (P, 3) from the bone
    distance = np.linalg.norm(out, axis=1, keepdims=True)
    return points + thickness * out / np.maximum(distance, 1e-12)


def cut_near_pivot(hull: np.ndarray | None, axis: np.ndarray, length: float, share: float) -> np.ndarray | None:
    """The part of the convex hull of ``hull`` (P, 3 points relative to a link's head) at least
    ``share`` x ``length`` metres along unit ``axis`` from the head (the pivot): the hull of its
    points past that plane and of the points where segments between points on either side cross
    it (the hull clipped by the plane, at most :data:`MAX_LINK_HULL_POINTS` of its points);
    ``hull`` unchanged when ``share`` is 0 or the part spans no volume."""
    if hull is None or share <= 0:
        return hull
    points = np.asarray(hull, np.float64)
    along = points @ axis - share * length  # (P,) signed distance past the plane
    beyond, before = points[along >= 0], points[along < 0]
    a, b = along[along >= 0][:, None], along[along < 0][None, :]
    t = (a / (a - b))[..., None]  # (B, A, 1) where each segment from a kept point crosses the plane
    crossings = (beyond[:, None] + t * (before[None] - beyond[:, None])).reshape(-1, 3)
    found = hull_points(np.concatenate([beyond, crossings]), max_points=MAX_LINK_HULL_POINTS)
    return hull if found is None else found[0]


def _gravity_torque(i: int, link_parents: list[int], heads, centres, masses, gravity: float) -> float:
    """Torque (N m) the links at and below link i exert about its joint when held horizontally."""
    below = {i}
    for j in range(i + 1, len(link_parents)):
        if link_parents[j] in below:
            below.add(j)
    return gravity * sum(masses[j] * np.linalg.norm(centres[j] - heads[i]) for j in below)


def build_chains(keypoints: np.ndarray, parents: np.ndarray, bone_names: list[str], roles: list[str] | None,
                 vertices: np.ndarray, owner: np.ndarray, apparel: np.ndarray, params: ApparelParams,
                 height: float) -> list[ChainSpec]:
    """The :class:`ChainSpec` of every apparel chain.

    Args:
        keypoints: (K, 3) rest joint heads, metres. parents: (K,) int.
        bone_names: K names; roles: K roles or None (the kind comes from either).
        vertices: (N, 3) rest vertices; owner: (N,) dominant bone of each vertex.
        apparel: (K,) bool apparel bones.
        params: chain parameters per kind.
        height: the character's height (metres), for fallback sizes.
    """
    keypoints = np.asarray(keypoints, np.float64)
    vertices = np.asarray(vertices, np.float64)
    parents = np.asarray(parents)
    apparel = np.asarray(apparel, bool)
    chains = []
    for root in chain_roots(parents, apparel):
        bones = _subtree(root, parents, apparel)
        kind = bone_kind(bone_names[root], roles[root] if roles else None)
        cp = params.for_kind(kind)
        index = {b: i for i, b in enumerate(bones)}
        link_parents = [index.get(int(parents[b]), -1) for b in bones]
        links = []
        for b, parent in zip(bones, link_parents):
            axis, length, spread, hull = _link_geometry(b, bones, parents, keypoints, vertices, owner, height)
            if parent >= 0 and cp.contact_frequency > 0:
                hull = shell(hull, axis, length, cp.contact_shell)
            if parent < 0:
                hull = cut_near_pivot(hull, axis, length, cp.root_hull_from)
            links.append(LinkSpec(bone=b, head=keypoints[b].copy(), axis=axis, length=length,
                                  radius=spread * cp.radius_scale, mass=cp.link_mass,
                                  linear_damping=cp.linear_damping, angular_damping=cp.angular_damping,
                                  friction=cp.friction, hull=hull, axial_share=cp.axial_inertia,
                                  contact_frequency=cp.root_contact_frequency if parent < 0 else cp.contact_frequency))
        heads = [link.head for link in links]
        centres = [link.head + 0.5 * link.length * link.axis for link in links]
        masses = [link.mass for link in links]
        joints = tuple(JointSpec(swing_limit=cp.swing_limit, twist_limit=cp.twist_limit, stiffness=cp.stiffness,
                                 damping=cp.damping,
                                 max_torque=cp.strength * _gravity_torque(i, link_parents, heads, centres, masses,
                                                                          params.simulation.gravity))
                       for i in range(len(links)))
        mask = 0b01 if cp.collide_body else 0
        if cp.collide_chains:
            mask |= 0b10
        chains.append(ChainSpec(name=bone_names[root], kind=kind, anchor_bone=int(parents[root]), links=tuple(links),
                                link_parents=tuple(link_parents), joints=joints, collision_group=0b10,
                                collision_mask=mask))
    return chains
