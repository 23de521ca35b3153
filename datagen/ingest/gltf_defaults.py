"""The default pose of a glTF file's nodes (glTF 2.0 section 3.5: each node at its own
``matrix`` or TRS, world = parent world @ local), read from the file's JSON alone.

Blender's glTF importer makes the armature's rest pose the bind pose guessed from the inverse
bind matrices, which is what linear blend skinning needs; a bone that a clip does not animate
must still take its node's own TRS (the default pose), which can differ from the bind pose.
Ingest uses these matrices to pose such bones (see :mod:`mimicbench.datagen.ingest.blender_child`).
NumPy and the standard library only (this runs inside the Blender child process).
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import quat_to_matrix


def local_matrix(node: dict) -> np.ndarray:
    """(4, 4) local transform of a glTF node: its ``matrix`` (column-major) or T @ R @ S."""
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(np.array([w, x, y, z], np.float64)) * np.asarray(node.get("scale", [1.0, 1.0, 1.0]))[None, :]
    m[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return m


def default_world_matrices(doc: dict) -> dict[str, np.ndarray]:
    """Node name -> (4, 4) world matrix in the default pose (glTF frame: Y up, +Z forward).

    Only nodes whose name is unique in the file are listed (a repeated or missing name cannot
    be matched with a Blender bone).
    """
    nodes = doc.get("nodes") or []
    parent = [-1] * len(nodes)
    for i, n in enumerate(nodes):
        for c in n.get("children", []):
            parent[c] = i
    world: dict[int, np.ndarray] = {}

    def visit(i: int) -> np.ndarray:
        if i not in world:
            local = local_matrix(nodes[i])
            world[i] = local if parent[i] < 0 else visit(parent[i]) @ local
        return world[i]

    names = [n.get("name") for n in nodes]
    return {name: visit(i) for i, name in enumerate(names) if name and names.count(name) == 1}
