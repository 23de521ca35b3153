"""Semantic agreement of a transfer: did the target's arm move as the source's arm did?

The cycle of ``cct`` round-trips any one-to-one bone mapping, so a transfer that drives the
target's right arm with the source's left arm costs it nothing. This score looks at the forward
prediction alone, against ground truth that methods never receive: each character's hidden role
classes (:func:`mimicbench.datagen.correspond.roles.role_classes`: arm ~ front leg ~ wing ~ pectoral fin,
sides kept; real characters get them from a role-label file).

Definition (one case, source S posed, target T predicted):

1. **Body frame.** The rotation ``R_body`` that best maps the rest torso to the posed torso
   (weighted Kabsch over the vertices, each weighted by its skin weight on ``root`` and ``spine``
   bones; all vertices when a skeleton has no such bone).
2. **A part's direction.** For each role class ``c`` other than ``root``, ``spine`` and
   ``apparel`` (``left/forelimb``, ``tail``, ``head``, ...), its bones are ordered by depth along
   the class (how many ancestors of the same class a bone has). The proximal region is the
   shallowest depths holding half the class's skin-weight mass, the distal region the rest; with a
   single depth the proximal region is the parent of the class's first bone. The direction is
   the unit vector from the proximal region's weighted vertex centroid to the distal one's, at
   rest (``d0``) and posed, the posed one taken back into the body frame (``d1 = R_body^T d``).
3. **How it moved.** The rotation vector ``w`` (axis times angle, radians) of the shortest rotation
   from ``d0`` to ``d1``: the part's swing in the character's own body frame.
4. **Agreement.** Characters of different kinds rest differently (a humanoid's arm out sideways,
   a dog's foreleg down), so the source's swing is carried into the target's rest by the shortest
   rotation ``A`` taking the source's rest direction to the target's: an arm raised forward and a
   foreleg raised forward then agree. The part's disagreement is ``|A w_S - w_T|`` in degrees; the
   body's is the angle between ``R_body`` of the two.

``semantic_deg`` is the mean disagreement over the body and every class both characters have
(0 for a transfer that moves every shared part as the source's; a target left at rest scores the
mean size of the source's swings). ``role_classes_scored`` counts the parts averaged, body included.
The score reads only vertices and the characters' ground-truth weights and roles: never the method's
own reading of a skeleton.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.datagen.correspond.roles import role_classes

FRAME_CLASSES = frozenset({"root", "spine"})
"""Classes that define the body frame rather than being scored as parts."""

UNSCORED_CLASSES = FRAME_CLASSES | {"apparel"}


@dataclass(frozen=True)
class PartRegions:
    """Per scored role class, the per-vertex weights of its proximal and distal regions.

    Attributes:
        torso: (N,) weight of each vertex on the body-frame bones.
        parts: class name -> ((N,) proximal weights, (N,) distal weights).
    """

    torso: np.ndarray
    parts: dict


def character_role_classes(record) -> list | None:
    """K role classes of a character record from its hidden ``bone_roles`` (None for an unlabelled
    bone); None when the character has no labels at all."""
    roles = list(record.bone_roles or [])
    labelled = [k for k, r in enumerate(roles) if r]
    if len(roles) != len(record.parents) or not labelled:
        return None
    out = [None] * len(roles)
    for k, cls in zip(labelled, role_classes([roles[k] for k in labelled], record.category)):
        out[k] = cls
    return out


def _region_weight(weights, bones: np.ndarray) -> np.ndarray:
    """(N,) each vertex's total skin weight on the bones in boolean mask ``bones`` (K,)."""
    return (np.asarray(weights.values, np.float64) * bones[np.asarray(weights.indices)]).sum(axis=1)


def _class_depths(classes: list, parents: np.ndarray, members: np.ndarray) -> np.ndarray:
    """(K,) for the bones in ``members``, how many of their ancestors share their class; -1 elsewhere."""
    depth = np.full(len(parents), -1)
    for k in range(len(parents)):
        if not members[k]:
            continue
        d, p = 0, parents[k]
        while p >= 0:
            if classes[p] == classes[k]:
                d += 1
            p = parents[p]
        depth[k] = d
    return depth


def part_regions(weights, parents, classes: list) -> PartRegions:
    """The torso and the proximal/distal regions of every scored class of one character.

    Args:
        weights: :class:`mimicbench.schemas.weights.SparseWeights` over K bones.
        parents: (K,) parent indices, -1 for roots.
        classes: K role classes (``left/forelimb``, ``tail``, ...; None for an unlabelled bone).
    """
    parents = np.asarray(parents)
    if len(classes) != len(parents):
        raise ValueError(f"classes: expected {len(parents)} entries (one per bone), got {len(classes)}")
    base = [c.split("/")[-1] if c else None for c in classes]
    torso_bones = np.array([b in FRAME_CLASSES for b in base])
    n = int(np.asarray(weights.indices).shape[0])
    torso = _region_weight(weights, torso_bones) if torso_bones.any() else np.ones(n)
    if torso.sum() <= 0:
        torso = np.ones(n)
    parts = {}
    for cls in sorted({c for c, b in zip(classes, base) if c and b not in UNSCORED_CLASSES}):
        members = np.array([c == cls for c in classes])
        depth = _class_depths(classes, parents, members)
        mass = np.array([_region_weight(weights, depth == d).sum() for d in range(depth.max() + 1)])
        if mass.sum() <= 0:
            continue
        if len(mass) > 1:
            cut = int(np.searchsorted(np.cumsum(mass), 0.5 * mass.sum()))
            cut = min(cut, len(mass) - 2)
            proximal = _region_weight(weights, members & (depth <= cut))
            distal = _region_weight(weights, members & (depth > cut))
        else:
            first = np.flatnonzero(members & (depth == 0))
            anchor = np.zeros(len(parents), bool)
            anchor[[parents[k] for k in first if parents[k] >= 0]] = True
            if not anchor.any():
                continue
            proximal = _region_weight(weights, anchor)
            distal = _region_weight(weights, members)
        if proximal.sum() > 0 and distal.sum() > 0:
            parts[cls] = (proximal, distal)
    return PartRegions(torso, parts)


def _centroid(w: np.ndarray, v: np.ndarray) -> np.ndarray:
    return (w[:, None] * v).sum(axis=0) / w.sum()


def body_rotation(rest: np.ndarray, posed: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(3, 3) rotation best mapping rest vertices (N, 3) to posed (N, 3), weights w (N,) (Kabsch)."""
    a = rest - _centroid(w, rest)
    b = posed - _centroid(w, posed)
    u, _, vt = np.linalg.svd((w[:, None] * a).T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def shortest_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3,) rotation vector (axis times angle, radians) of the shortest rotation taking unit ``a`` to unit ``b``."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    angle = np.arctan2(s, c)
    if s < 1e-12:
        if c > 0:
            return np.zeros(3)
        helper = np.eye(3)[np.argmin(np.abs(a))]
        axis = np.cross(a, helper)
        s = np.linalg.norm(axis)
    return axis / s * angle


def rotation_matrix(w: np.ndarray) -> np.ndarray:
    """(3, 3) matrix of rotation vector ``w`` (3,) (Rodrigues)."""
    angle = np.linalg.norm(w)
    if angle < 1e-15:
        return np.eye(3)
    k = w / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


@dataclass(frozen=True)
class PartMotion:
    """How a character's parts moved from rest.

    Attributes:
        body: (3, 3) body rotation (rest to posed).
        rest_dirs: class -> (3,) unit direction at rest.
        swings: class -> (3,) rotation vector of the part's swing in the body frame, radians.
    """

    body: np.ndarray
    rest_dirs: dict
    swings: dict


def part_motion(rest: np.ndarray, posed: np.ndarray, regions: PartRegions) -> PartMotion:
    """The body rotation and each part's swing of one posed mesh (N, 3) against its rest (N, 3)."""
    rest = np.asarray(rest, np.float64)
    posed = np.asarray(posed, np.float64)
    r_body = body_rotation(rest, posed, regions.torso)
    rest_dirs, swings = {}, {}
    for cls, (prox, dist) in regions.parts.items():
        d0 = _centroid(dist, rest) - _centroid(prox, rest)
        d1 = r_body.T @ (_centroid(dist, posed) - _centroid(prox, posed))
        n0, n1 = np.linalg.norm(d0), np.linalg.norm(d1)
        if n0 < 1e-9 or n1 < 1e-9:
            continue
        rest_dirs[cls] = d0 / n0
        swings[cls] = shortest_rotation(d0 / n0, d1 / n1)
    return PartMotion(r_body, rest_dirs, swings)


def rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle in degrees of the rotation between (3, 3) rotations ``a`` and ``b``."""
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def semantic_disagreement(source: PartMotion, target: PartMotion) -> dict:
    """Per part, degrees of disagreement between the target's motion and the source's.

    Returns ``{"body": deg, "<class>": deg, ...}`` over the body and the classes both have.
    """
    out = {"body": rotation_angle_deg(source.body, target.body)}
    for cls in sorted(set(source.swings) & set(target.swings)):
        carry = rotation_matrix(shortest_rotation(source.rest_dirs[cls], target.rest_dirs[cls]))
        out[cls] = float(np.degrees(np.linalg.norm(carry @ source.swings[cls] - target.swings[cls])))
    return out


def semantic_scores(source_motion: PartMotion, target_motion: PartMotion) -> dict:
    """The result columns: ``semantic_deg`` (mean over parts, degrees) and ``role_classes_scored``."""
    parts = semantic_disagreement(source_motion, target_motion)
    return {"semantic_deg": float(np.mean(list(parts.values()))), "role_classes_scored": len(parts)}
