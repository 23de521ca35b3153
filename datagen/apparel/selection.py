"""Which bones are apparel, which vertices they drive, and which kind each chain is.

A zoo character carries ``apparel_bone_mask`` and roles ``apparel/<kind>/<chain>/<segment>``.
For an ingested character the user names the apparel bones with glob patterns on bone names
(``--apparel-bones '*hair*' '*skirt*'``); the vertex mask then follows the weights: a vertex is
apparel when apparel bones hold more than half of its skin weight.
"""
from __future__ import annotations

import fnmatch

import numpy as np

from mimicbench.schemas.weights import as_dense

KNOWN_KINDS = ("skirt", "hair", "ponytail", "cape", "coat_tail", "tail", "sleeve", "ribbon", "chain")


def bones_matching(bone_names: list[str], patterns: list[str]) -> np.ndarray:
    """(K,) bool: bones whose name matches any glob in ``patterns`` (case-insensitive)."""
    pats = [p.lower() for p in patterns]
    return np.array([any(fnmatch.fnmatchcase(n.lower(), p) for p in pats) for n in bone_names], bool)


def apparel_vertex_mask(weights, bone_mask: np.ndarray) -> np.ndarray:
    """(N,) bool: vertices whose skin weight on apparel bones exceeds one half.

    Args:
        weights: :class:`~mimicbench.schemas.weights.SparseWeights` or dense (N, K).
        bone_mask: (K,) bool apparel bones.
    """
    dense = as_dense(weights, len(bone_mask))
    return dense[:, np.asarray(bone_mask, bool)].sum(axis=1) > 0.5


def selection_problem(bone_names: list[str], parents: np.ndarray, bones: np.ndarray, vertices: np.ndarray) -> str | None:
    """Why the apparel ``bones`` (K,) bool of a skeleton (``parents`` (K,), -1 for a root) cannot be
    simulated as chains, or None. A chain hangs from a body bone that carries it, so the body keeps
    at least one bone and every apparel bone has a body bone above it; and the apparel bones must
    own some vertex (``vertices`` (N,) bool, :func:`apparel_vertex_mask`), or there is nothing to move."""
    bones = np.asarray(bones, bool)
    if bones.all():
        return (f"the apparel bones are every bone of the skeleton ({len(bones)}); a chain hangs from a body bone, so "
                f"leave the body at least its root (narrow --apparel-bones)")
    parents = np.asarray(parents, np.int64)
    for k in np.flatnonzero(bones):
        j = k
        while j >= 0 and bones[j]:
            j = parents[j]
        if j < 0:
            return (f"apparel bone {bone_names[k]!r} hangs from no body bone (no body bone above it up to the root); "
                    f"a chain must hang from the body (narrow --apparel-bones)")
    if not np.asarray(vertices, bool).any():
        return (f"the {int(bones.sum())} apparel bones hold more than half the skin weight of no vertex: nothing to "
                f"simulate (widen --apparel-bones to the bones that drive the apparel)")
    return None


def bone_kind(name: str, role: str | None) -> str:
    """The apparel kind of a bone: from a role ``apparel/<kind>/...``, else a known kind named in
    the bone name (``Hair_L_03`` -> ``hair``), else ``default``."""
    if role and role.startswith("apparel/"):
        return role.split("/")[1]
    low = name.lower().replace("-", "_").replace(" ", "_")
    for kind in sorted(KNOWN_KINDS, key=len, reverse=True):  # coat_tail before tail
        if kind in low:
            return kind
    return "default"


def dominant_bone(weights, num_bones: int) -> np.ndarray:
    """(N,) the bone holding each vertex's largest skin weight."""
    return np.argmax(as_dense(weights, num_bones), axis=1)
