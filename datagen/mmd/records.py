"""An :class:`MMDModel` as the dataset's character record.

Bones are put in topological order (parents first, file order otherwise kept); positions go to
metres in the dataset frame (:mod:`mimicbench.datagen.mmd.frame`); faces are reversed to stay
counter-clockwise seen from outside after the mirror; BDEF1/2/4 weights are summed per bone
(SDEF as BDEF2, its C/R0/R1 kept in ``meta["mmd"]["sdef"]``; QDEF as BDEF4) and renormalised. Japanese names are kept as authored; the English
canonical name, the file's own English name, and the IK, twist and grant (付与) roles of each bone
go to ``meta["mmd"]``.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from mimicbench.datagen.mmd import frame
from mimicbench.datagen.mmd.apparel import apparel_bones, apparel_chains, apparel_vertex_mask
from mimicbench.datagen.mmd.errors import MMDFormatError
from mimicbench.datagen.mmd.model import DEFORM_NAMES, MMDModel
from mimicbench.datagen.mmd.names import english_name
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.weights import SparseWeights

# Bones every MMD humanoid has (standard bone set): their presence makes the category humanoid
HUMANOID_BONES = ("上半身", "下半身", "頭", "左腕", "右腕", "左足", "右足", "左ひざ", "右ひざ")


def topological_order(parents: np.ndarray, name: str = "<model>") -> np.ndarray:
    """(K,) file indices in an order where each parent comes before its children (file order
    kept where it already is); raises :class:`MMDFormatError` on a parent cycle."""
    k = len(parents)
    placed = np.zeros(k, bool)
    order: list[int] = []
    children: dict[int, list[int]] = {}
    for i, p in enumerate(parents):
        children.setdefault(int(p), []).append(i)
    # Kahn's algorithm with a heap keyed by file index keeps the file order when it is valid
    import heapq

    ready = [i for i in children.get(-1, [])]
    heapq.heapify(ready)
    while ready:
        i = heapq.heappop(ready)
        placed[i] = True
        order.append(i)
        for c in children.get(i, []):
            heapq.heappush(ready, c)
    if len(order) != k:
        bad = int(np.flatnonzero(~placed)[0])
        raise MMDFormatError(f"{name}: bone {bad} is in a parent cycle (no path to a root)")
    return np.asarray(order, np.int64)


def bone_roles(model: MMDModel) -> list[list[str]]:
    """Per bone (file order), its MMD roles: ``ik`` (an IK bone), ``ik_target``, ``ik_link``,
    ``twist`` (fixed axis or 捩 in the name), ``grant`` (付与: copies another bone's rotation or
    translation), ``after_physics``."""
    roles = [[] for _ in model.bones]
    for i, b in enumerate(model.bones):
        if b.ik is not None:
            roles[i].append("ik")
            roles[b.ik.target].append("ik_target")
            for link in b.ik.links:
                roles[link.bone].append("ik_link")
        if b.fixed_axis is not None or "捩" in b.name:
            roles[i].append("twist")
        if b.grant_rotation or b.grant_translation:
            roles[i].append("grant")
        if b.after_physics:
            roles[i].append("after_physics")
    return [sorted(set(r)) for r in roles]


def skin_weights(model: MMDModel, new_index: np.ndarray, name: str) -> tuple[SparseWeights, int]:
    """The vertices' weights over the reordered bones (N, 8), duplicates summed, renormalised.

    A vertex whose listed weights are all zero gets weight 1 on its first listed bone (counted in
    the second return value); a vertex that lists no bone at all is an error."""
    from scipy.sparse import coo_matrix

    n, k = len(model.positions), len(model.bones)
    wb, ww = model.weight_bones, model.weight_values.astype(np.float64)
    valid = (wb >= 0) & (ww > 0)
    rows_sum = np.where(valid, ww, 0).sum(axis=1)
    empty = rows_sum <= 0
    if empty.any():
        listed = (wb >= 0)
        none = empty & ~listed.any(axis=1)
        if none.any():
            raise MMDFormatError(f"{name}: vertex {int(np.flatnonzero(none)[0])} lists no bone in its weights")
        first = np.argmax(listed, axis=1)
        rows = np.flatnonzero(empty)
        valid[rows] = False
        valid[rows, first[rows]] = True
        ww = ww.copy()
        ww[rows, first[rows]] = 1.0
    r, c = np.nonzero(valid)
    m = coo_matrix((ww[r, c], (r, new_index[wb[r, c]])), shape=(n, k))
    return SparseWeights.from_csr(m), int(empty.sum())


SDEF_SKINNING = ("BDEF2: the vertex is skinned by linear blend skinning with the file's weights w and 1 - w on "
                 "its two bones; MMD's SDEF would instead blend about C between R0 and R1 (kept here)")


def sdef_meta(model: MMDModel, scale: float) -> dict:
    """The SDEF vertices' parameters as ``meta.mmd.sdef``: ``vertices`` (S,) vertex indices (the
    dataset keeps the file's vertex order), ``c``, ``r0``, ``r1`` (S, 3) metres in the dataset
    frame, and ``skinning``, how the dataset skins them (:data:`SDEF_SKINNING`)."""
    pts = frame.point(np.asarray(model.sdef, np.float64).reshape(-1, 3, 3), scale)
    return {"skinning": SDEF_SKINNING, "vertices": np.asarray(model.sdef_vertices).tolist(),
            "c": pts[:, 0].tolist(), "r0": pts[:, 1].tolist(), "r1": pts[:, 2].tolist()}


def character_from_mmd(model: MMDModel, character_id: str, source: str, split: str, category: str = "unknown",
                       scale: float = frame.MMD_UNIT_METRES) -> CharacterRecord:
    """The character record of ``model`` (see the module docstring); ``scale`` metres per MMD unit."""
    parents_file = np.array([b.parent for b in model.bones], np.int64)
    order = topological_order(parents_file, source)
    new_index = np.empty(len(order), np.int64)
    new_index[order] = np.arange(len(order))
    parents = np.array([-1 if parents_file[i] < 0 else new_index[parents_file[i]] for i in order], np.int32)
    names = [model.bones[i].name for i in order]
    keypoints = frame.point(np.array([model.bones[i].position for i in order]).reshape(-1, 3), scale)
    vertices = frame.point(model.positions, scale).astype(np.float32)
    faces = model.faces[:, [0, 2, 1]].astype(np.int32)  # mirrored: reverse the winding
    weights, reweighted = skin_weights(model, new_index, source)

    bone_mask_file = apparel_bones(model)
    bone_mask = bone_mask_file[order]
    vertex_mask = apparel_vertex_mask(weights.indices, weights.values, bone_mask)
    chains = apparel_chains(model, bone_mask_file)
    for ch in chains:
        ch["root"] = int(new_index[ch["root"]])
        ch["bones"] = sorted(int(new_index[j]) for j in ch["bones"])

    how = {"value": category, "source": "map"} if category != "unknown" else \
        {"value": category, "source": "inferred", "evidence": {"rule": "no rule fits"}}
    if category == "unknown" and all(n in set(names) for n in HUMANOID_BONES):
        category = "humanoid"
        how = {"value": category, "source": "inferred", "evidence": {"rule": "the MMD standard bone set"}}
    english, english_how = zip(*[english_name(model.bones[i].name, model.bones[i].name_en) for i in order]) \
        if len(order) else ((), ())
    roles_file = bone_roles(model)
    grants = []
    for i in order:
        b = model.bones[i]
        if b.grant_rotation or b.grant_translation:
            grants.append({"bone": int(new_index[i]), "parent": int(new_index[b.grant_parent]),
                           "ratio": float(b.grant_ratio), "rotation": b.grant_rotation,
                           "translation": b.grant_translation, "local": bool(b.flags & 0x0080)})
    iks = []
    for i in order:
        ik = model.bones[i].ik
        if ik is None:
            continue
        links = []
        for link in ik.links:
            entry = {"bone": int(new_index[link.bone])}
            if link.limit_min is not None:
                lo, hi = frame.interval(link.limit_min, link.limit_max, frame.ANGLE_MIRROR)
                entry["limit_min"], entry["limit_max"] = lo.tolist(), hi.tolist()
            links.append(entry)
        iks.append({"bone": int(new_index[i]), "target": int(new_index[ik.target]), "loop": int(ik.loop),
                    "unit_angle": float(ik.limit_angle), "links": links})
    skeleton_key = json.dumps([names, parents.tolist()], ensure_ascii=False).encode()
    deform_counts = {DEFORM_NAMES[t]: int((model.deform == t).sum()) for t in range(len(DEFORM_NAMES))}
    meta = {"mmd": {
        "format": model.format, "model_name": model.name, "model_name_en": model.name_en,
        "metres_per_unit": scale, "frame": "mirrored z (MMD left-handed -> right-handed Y up, +Z forward)",
        "file_bone_index": order.tolist(),
        "english_names": list(english), "english_name_source": list(english_how),
        "file_english_names": [model.bones[i].name_en for i in order],
        "bone_roles": [roles_file[i] for i in order],
        "deform_layer": [int(model.bones[i].layer) for i in order],
        "grants": grants, "ik": iks, "deform_counts": deform_counts, "reweighted_vertices": reweighted,
        "apparel_chains": chains, "apparel_mask_rule": "weights on apparel bones sum to >= 0.5",
        "sdef": sdef_meta(model, scale),
        "materials": model.num_materials, "morphs": model.num_morphs,
        "rigid_bodies": len(model.rigid_bodies), "joints": len(model.joints),
    }, "category": how}
    height = float(np.ptp(vertices[:, 1])) if len(vertices) else None
    return CharacterRecord(
        character_id=character_id, category=category, source=source, split=split, vertices=vertices, faces=faces,
        keypoints=keypoints.astype(np.float32), parents=parents, bone_names=names,
        weight_indices=weights.indices, weight_values=weights.values, apparel_vertex_mask=vertex_mask,
        apparel_bone_mask=bone_mask, bone_roles=None,
        skeleton_id="mmd/" + hashlib.sha256(skeleton_key).hexdigest()[:16], height=height, meta=meta)
