"""Small labelled rigs for the semantic score, the role match and the probes: boxes of vertices
along each bone, each vertex bound rigidly to one bone, so poses and part directions are known by hand."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from mimicbench.benchmark.request import Rig
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_identity
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.weights import SparseWeights


def segment_cloud(a, b, n: int = 12, radius: float = 0.02) -> np.ndarray:
    """(n * 4, 3) points along the segment a -> b, four around each of n stations."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = (np.arange(n) + 0.5) / n
    axis = (b - a) / np.linalg.norm(b - a)
    side = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    up = np.cross(axis, side)
    ring = [radius * side, -radius * side, radius * up, -radius * up]
    return np.array([a + ti * (b - a) + r for ti in t for r in ring])


def labelled_rig(joints: dict, name: str = "toy", category: str = "humanoid"):
    """A rig from ``{bone: (head (3,), tail (3,), parent name or None, role)}`` in order (parents first).

    Returns a namespace with ``rig`` (:class:`mimicbench.benchmark.request.Rig`), ``record`` (character-record-like:
    ``bone_roles``, ``parents``, ``category``, ``keypoints``, ``vertices``, ``weights``, ``character_id``)
    and ``names``.
    """
    names = list(joints)
    parents = np.array([-1 if joints[b][2] is None else names.index(joints[b][2]) for b in names], np.int32)
    keypoints = np.array([joints[b][0] for b in names], np.float32)
    clouds = [segment_cloud(joints[b][0], joints[b][1]) for b in names]
    vertices = np.concatenate(clouds).astype(np.float32)
    owner = np.concatenate([np.full(len(c), k) for k, c in enumerate(clouds)])
    weights = SparseWeights(owner[:, None].astype(np.int32), np.ones((len(owner), 1), np.float32), len(names))
    faces = np.array([[0, 1, 2]], np.int32)
    rig = Rig(name, category, vertices, faces, keypoints, parents, weights, tuple(names))
    roles = [joints[b][3] for b in names]
    record = SimpleNamespace(character_id=name, category=category, bone_roles=roles, parents=parents,
                             keypoints=keypoints, vertices=vertices, weights=weights, bone_names=names,
                             skeleton_id=name)
    return SimpleNamespace(rig=rig, record=record, names=names)


def pose(rig, local: dict, root_shift=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Transforms (K, 7) and posed vertices (N, 3) of ``rig`` with local rotations
    ``{bone index: (axis (3,), degrees)}`` (others at rest)."""
    q = quat_identity((len(rig.parents),))
    for k, (axis, deg) in local.items():
        q[k] = quat_from_axis_angle(np.asarray(axis, float), np.radians(deg))
    roots = np.array(rig.keypoints, np.float64)
    roots[rig.parents < 0] += np.asarray(root_shift)
    g_rot, g_pos = forward_kinematics(q, rig.keypoints, rig.parents, roots)
    t = transforms_to_array(g_rot, g_pos)
    return t, linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, t)


def t_pose_humanoid(name: str = "t_pose", extra_spine: bool = False):
    """Hips, spine (one or two bones), head; arms out sideways (+x is the character's left); legs down."""
    j = {"hips": ((0, 1.0, 0), (0, 1.1, 0), None, "hips"),
         "spine": ((0, 1.1, 0), (0, 1.3, 0), "hips", "spine/1")}
    top = "spine"
    if extra_spine:
        j["chest"] = ((0, 1.3, 0), (0, 1.45, 0), "spine", "spine/2")
        top = "chest"
    y = 1.45 if extra_spine else 1.3
    j.update({
        "head": ((0, y, 0), (0, y + 0.2, 0), top, "head"),
        "l_arm": ((0.1, y, 0), (0.4, y, 0), top, "left/upper_arm"),
        "l_fore": ((0.4, y, 0), (0.7, y, 0), "l_arm", "left/forearm"),
        "r_arm": ((-0.1, y, 0), (-0.4, y, 0), top, "right/upper_arm"),
        "r_fore": ((-0.4, y, 0), (-0.7, y, 0), "r_arm", "right/forearm"),
        "l_thigh": ((0.1, 1.0, 0), (0.1, 0.5, 0), "hips", "left/thigh"),
        "l_shin": ((0.1, 0.5, 0), (0.1, 0.0, 0), "l_thigh", "left/shin"),
        "r_thigh": ((-0.1, 1.0, 0), (-0.1, 0.5, 0), "hips", "right/thigh"),
        "r_shin": ((-0.1, 0.5, 0), (-0.1, 0.0, 0), "r_thigh", "right/shin"),
    })
    return labelled_rig(j, name)


def quadruped(name: str = "dog"):
    """A body along +z (head forward), four legs straight down."""
    j = {"hips": ((0, 0.6, -0.3), (0, 0.6, -0.1), None, "hips"),
         "spine": ((0, 0.6, -0.1), (0, 0.6, 0.3), "hips", "spine/1"),
         "head": ((0, 0.6, 0.3), (0, 0.7, 0.5), "spine", "head")}
    for side, x in (("left", 0.12), ("right", -0.12)):
        s = side[0]
        j[f"{s}_front"] = ((x, 0.6, 0.25), (x, 0.3, 0.25), "spine", f"{side}/front_leg/1")
        j[f"{s}_front2"] = ((x, 0.3, 0.25), (x, 0.0, 0.25), f"{s}_front", f"{side}/front_leg/2")
        j[f"{s}_hind"] = ((x, 0.6, -0.25), (x, 0.3, -0.25), "hips", f"{side}/hind_leg/1")
        j[f"{s}_hind2"] = ((x, 0.3, -0.25), (x, 0.0, -0.25), f"{s}_hind", f"{side}/hind_leg/2")
    return labelled_rig(j, name, "quadruped")
