"""Read PMD files (MikuMikuDance's original model format, version 1.0) into :class:`MMDModel`,
in PMX's terms, with the conversions MMD and PMX Editor make:

- each vertex's two bones and weight (0..100) become BDEF1 (100 or 0) or BDEF2;
- bone types: 5 (rotation follows) becomes a grant rotation of ratio 1 from the bone in its IK
  field, 9 (rotation linked) a grant rotation from its tail bone with ratio IK field / 100,
  8 (twist) a fixed axis along the bone; 2 marks the IK bone;
- IK: the per-iteration unit angle is 4 x the stored control weight (radians); links whose name
  contains ひざ (knee) get MMD's knee limit (x in [-pi, -0.5 deg]);
- rigid-body positions are offsets from their bone's head (a body with bone -1 from bone 0),
  converted here to model-space positions.

The English-name, toon and physics sections are optional (older files end earlier). Every count
is checked against the bytes left before anything is read.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mimicbench.datagen.mmd.binary import BoundedReader, check_indices
from mimicbench.datagen.mmd.errors import MMDFormatError
from mimicbench.datagen.mmd.model import (BONE_FIXED_AXIS, BONE_GRANT_ROTATION, BONE_IK, BONE_MOVABLE, BONE_OPERABLE,
                               BONE_ROTATABLE, BONE_TAIL_IS_BONE, BONE_VISIBLE, IKChain, IKLink, MMDBone, MMDJoint,
                               MMDModel, MMDRigidBody)

MAGIC = b"Pmd"
KNEE_MIN = np.array([-np.pi, 0.0, 0.0], np.float32)
KNEE_MAX = np.array([-np.radians(0.5), 0.0, 0.0], np.float32)
NONE16 = 0xFFFF


def read_pmd(path) -> MMDModel:
    """Read a PMD file; raises :class:`MMDFormatError` naming the file for anything malformed."""
    path = Path(path)
    return parse_pmd(path.read_bytes(), str(path))


def parse_pmd(data: bytes, name: str = "<pmd>") -> MMDModel:
    """Parse PMD bytes (see :func:`read_pmd`); ``name`` is used in errors."""
    r = BoundedReader(data, name)
    magic = bytes(r.take(3, "magic"))
    if magic != MAGIC:
        raise r.fail(f"wrong magic {magic!r}, expected {MAGIC!r} (not a PMD file)")
    version = r.float("version")
    if version != 1.0:
        raise r.fail(f"PMD version {version:g}, expected 1")
    model_name = r.fixed_text(20, "model name")
    comment = r.fixed_text(256, "comment")

    nv = r.count("vertices", 38)
    vt = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", 2), ("b", "<u2", 2), ("w", "u1"), ("e", "u1")])
    v = np.frombuffer(r.take(nv * vt.itemsize, "vertices"), vt)
    positions, normals = v["p"].astype(np.float32), v["n"].astype(np.float32)
    if not (np.isfinite(positions).all() and np.isfinite(normals).all()):
        raise MMDFormatError(f"{name}: non-finite vertex position or normal")
    if (v["w"] > 100).any():
        raise MMDFormatError(f"{name}: vertex weight {int(v['w'].max())}, expected 0..100")
    w0 = v["w"].astype(np.float32) / 100.0
    wb = np.full((nv, 4), -1, np.int32)
    ww = np.zeros((nv, 4), np.float32)
    wb[:, :2] = v["b"]
    ww[:, 0], ww[:, 1] = w0, 1.0 - w0
    deform = np.where((v["w"] == 0) | (v["w"] == 100), 0, 1).astype(np.int8)
    one = deform == 0
    wb[one, 0] = np.where(v["w"][one] == 100, v["b"][one, 0], v["b"][one, 1])
    ww[one, 0], wb[one, 1], ww[one, 1] = 1.0, -1, 0.0

    nidx = r.count("face indices", 2)
    if nidx % 3:
        raise r.fail(f"{nidx} face indices, expected a multiple of 3")
    faces = r.array("u2", (nidx // 3, 3), "face indices").astype(np.int64)
    check_indices(faces, nv, "face vertex", name, allow_minus_one=False)

    nmat = r.count("materials", 70)
    r.take(70 * nmat, "materials")

    nb = r.int(2, "bone count", signed=False)
    if nb * 39 > r.left:
        raise r.fail(f"bone count {nb}, but {r.left} bytes are left")
    raw_bones = []
    for i in range(nb):
        bname = r.fixed_text(20, f"bone {i} name")
        parent, tail, = r.unpack("HH", f"bone {i} parent and tail")
        btype = r.int(1, f"bone {i} type", signed=False)
        ikf = r.int(2, f"bone {i} IK field", signed=False)
        pos = r.floats(3, f"bone {i} position")
        raw_bones.append((bname, parent, tail, btype, ikf, pos))
    bones = []
    for i, (bname, parent, tail, btype, ikf, pos) in enumerate(raw_bones):
        flags = BONE_ROTATABLE | BONE_VISIBLE | BONE_OPERABLE | BONE_TAIL_IS_BONE
        b = MMDBone(bname, "", pos, -1 if parent == NONE16 else parent, 0, flags,
                    tail_bone=-1 if tail in (0, NONE16) else tail)
        if btype in (1, 2):
            b.flags |= BONE_MOVABLE
        if btype == 5 and ikf != NONE16:  # rotation follows another bone
            b.flags |= BONE_GRANT_ROTATION
            b.grant_parent, b.grant_ratio, b.layer = ikf, 1.0, 2
        if btype == 9 and tail not in (0, NONE16):  # rotation linked with ratio
            b.flags |= BONE_GRANT_ROTATION
            b.grant_parent, b.grant_ratio, b.tail_bone = tail, ikf / 100.0, -1
        bones.append(b)
    for i, b in enumerate(bones):
        check_indices([b.parent, b.tail_bone, b.grant_parent], nb, f"bone {i} ({b.name}) parent/tail/grant", name)
    for i, b in enumerate(bones):
        if raw_bones[i][3] == 8 and b.tail_bone >= 0:  # twist: axis along the bone
            d = bones[b.tail_bone].position - b.position
            if np.linalg.norm(d) > 0:
                b.flags |= BONE_FIXED_AXIS
                b.fixed_axis = (d / np.linalg.norm(d)).astype(np.float32)
    check_indices(wb, nb, "vertex weight bone", name)

    nik = r.int(2, "IK count", signed=False)
    if nik * 11 > r.left:
        raise r.fail(f"IK count {nik}, but {r.left} bytes are left")
    for k in range(nik):
        ik_bone, target = r.unpack("HH", f"IK {k} bones")
        nlinks = r.int(1, f"IK {k} link count", signed=False)
        loop = r.int(2, f"IK {k} iterations", signed=False)
        weight = r.float(f"IK {k} control weight")
        links = [int(x) for x in r.array("u2", (nlinks,), f"IK {k} links")]
        check_indices([ik_bone, target] + links, nb, f"IK {k}", name, allow_minus_one=False)
        chain = IKChain(target, loop, 4.0 * weight, [])
        for lb in links:
            if "ひざ" in bones[lb].name:
                chain.links.append(IKLink(lb, KNEE_MIN.copy(), KNEE_MAX.copy()))
            else:
                chain.links.append(IKLink(lb))
        bones[ik_bone].ik = chain
        bones[ik_bone].flags |= BONE_IK

    nmorph = r.int(2, "morph count", signed=False)
    if nmorph * 25 > r.left:
        raise r.fail(f"morph count {nmorph}, but {r.left} bytes are left")
    morph_names = []
    for k in range(nmorph):
        morph_names.append(r.fixed_text(20, f"morph {k} name"))
        n = r.count(f"morph {k} vertices", 16)
        r.int(1, f"morph {k} type")
        r.take(16 * n, f"morph {k} offsets")
    r.take(2 * r.int(1, "morph display count", signed=False), "morph display list")
    n_frames = r.int(1, "bone frame count", signed=False)
    r.take(50 * n_frames, "bone frame names")
    r.take(3 * r.count("bone display entries", 3), "bone display list")

    model = MMDModel("PMD 1.0", model_name, "", comment, positions, normals, deform, wb, ww, faces, bones,
                     num_materials=nmat, num_morphs=max(nmorph - 1, 0), morph_names=morph_names[1:])
    if r.left == 0:
        return model
    if r.int(1, "English flag", signed=False):
        model.name_en = r.fixed_text(20, "English model name")
        r.take(256, "English comment")
        for b in bones:
            b.name_en = r.fixed_text(20, "English bone name")
        r.take(20 * max(nmorph - 1, 0), "English morph names")
        r.take(50 * n_frames, "English bone frame names")
    if r.left == 0:
        return model
    r.take(1000, "toon texture names")
    if r.left == 0:
        return model

    nr = r.count("rigid bodies", 83)
    for k in range(nr):
        rname = r.fixed_text(20, f"rigid body {k} name")
        bone = r.int(2, f"rigid body {k} bone", signed=False)
        bone = -1 if bone == NONE16 else bone
        group = r.int(1, f"rigid body {k} group", signed=False)
        mask = r.int(2, f"rigid body {k} mask", signed=False)
        shape = r.int(1, f"rigid body {k} shape", signed=False)
        f = r.floats(14, f"rigid body {k} geometry and physics")
        mode = r.int(1, f"rigid body {k} mode", signed=False)
        if shape > 2 or mode > 2 or group > 15:
            raise r.fail(f"rigid body {rname!r}: shape {shape}, mode {mode}, group {group}; expected shape 0..2, "
                         "mode 0..2, group 0..15")
        check_indices([bone], nb, f"rigid body {k} bone", name)
        if nb == 0:
            raise MMDFormatError(f"{name}: rigid body {k} in a model without bones")
        origin = bones[bone if bone >= 0 else 0].position  # PMD: offsets from the bone (bone 0 for -1)
        model.rigid_bodies.append(MMDRigidBody(rname, "", bone, group, mask, shape, f[0:3], f[3:6] + origin, f[6:9],
                                               float(f[9]), float(f[10]), float(f[11]), float(f[12]), float(f[13]),
                                               mode))
    nj = r.count("joints", 124)
    for k in range(nj):
        jname = r.fixed_text(20, f"joint {k} name")
        a, b = r.unpack("ii", f"joint {k} bodies")
        f = r.floats(24, f"joint {k} frame, limits and springs")
        model.joints.append(MMDJoint(jname, "", 0, a, b, f[0:3], f[3:6], f[6:9], f[9:12], f[12:15], f[15:18],
                                     f[18:21], f[21:24]))
    check_indices([j.body_a for j in model.joints] + [j.body_b for j in model.joints], nr, "joint rigid body", name)
    return model
