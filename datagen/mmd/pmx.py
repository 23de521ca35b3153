"""Read PMX 2.0 and 2.1 files (MikuMikuDance extended models) into :class:`MMDModel`.

Why not a library: pymeshio 3.0.1, the one Python reader that returns bones, rigid bodies and
joints, refuses any file with additional UVs ("extended uv is not supported"), does not know
PMX 2.1 (QDEF weights, flip/impulse morphs), and allocates whatever counts a header claims. This
reader follows the PMX 2.0/2.1 specification (PmxEditor's "PMX仕様.txt") with every count,
length and index checked (:mod:`mimicbench.datagen.mmd.binary`). Soft bodies (2.1) after the joints are not
read. Text is UTF-16LE or UTF-8 as the header says.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from mimicbench.datagen.mmd.binary import BoundedReader, check_indices
from mimicbench.datagen.mmd.errors import MMDFormatError
from mimicbench.datagen.mmd.model import (BONE_EXTERNAL_PARENT, BONE_FIXED_AXIS, BONE_GRANT_ROTATION, BONE_GRANT_TRANSLATION,
                               BONE_IK, BONE_LOCAL_AXIS, BONE_TAIL_IS_BONE, IKChain, IKLink, MMDBone, MMDJoint,
                               MMDModel, MMDRigidBody)

MAGIC = b"PMX "
_SIGNED = {1: "b", 2: "h", 4: "i"}
_UNSIGNED = {1: "B", 2: "H", 4: "i"}  # vertex indices: unsigned below 4 bytes
# Bytes each morph offset takes, by morph type, given the index sizes (v, b, m, mat, r)
_MORPH_KINDS = ("group", "vertex", "bone", "uv", "uv1", "uv2", "uv3", "uv4", "material", "flip", "impulse")


class _Header:
    def __init__(self, r: BoundedReader):
        magic = bytes(r.take(4, "magic"))
        if magic != MAGIC:
            raise r.fail(f"wrong magic {magic!r}, expected {MAGIC!r} (not a PMX file)")
        self.version = round(r.float("version"), 3)
        if self.version not in (2.0, 2.1):
            raise r.fail(f"PMX version {self.version:g}, expected 2.0 or 2.1")
        n = r.int(1, "header size", signed=False)
        if n < 8:
            raise r.fail(f"header has {n} globals, expected at least 8")
        g = bytes(r.take(n, "header globals"))
        if g[0] not in (0, 1):
            raise r.fail(f"text encoding {g[0]}, expected 0 (UTF-16LE) or 1 (UTF-8)")
        self.encoding = "utf-16-le" if g[0] == 0 else "utf-8"
        if g[1] > 4:
            raise r.fail(f"{g[1]} additional UVs, expected 0..4")
        self.extra_uv = g[1]
        sizes = g[2:8]
        for what, s in zip(("vertex", "texture", "material", "bone", "morph", "rigid body"), sizes):
            if s not in (1, 2, 4):
                raise r.fail(f"{what} index size {s}, expected 1, 2 or 4")
        self.vertex, self.texture, self.material, self.bone, self.morph, self.rigid = sizes


def read_pmx(path) -> MMDModel:
    """Read a PMX file; raises :class:`MMDFormatError` naming the file for anything malformed."""
    path = Path(path)
    return parse_pmx(path.read_bytes(), str(path))


def parse_pmx(data: bytes, name: str = "<pmx>") -> MMDModel:
    """Parse PMX bytes (see :func:`read_pmx`); ``name`` is used in errors."""
    r = BoundedReader(data, name)
    h = _Header(r)
    enc = h.encoding

    def text(what):
        return r.text(enc, what)

    def idx(size, what):
        return r.int(size, what)

    model_name, model_name_en = text("model name"), text("model English name")
    comment = text("comment")
    text("English comment")

    # vertices: position, normal, uv, extra uvs, deform type + data, edge scale
    head = struct.Struct(f"<{8 + 4 * h.extra_uv}fB")
    vmin = head.size + h.bone + 4
    nv = r.count("vertices", vmin)
    positions = np.empty((nv, 3), np.float32)
    normals = np.empty((nv, 3), np.float32)
    deform = np.empty(nv, np.int8)
    wb = np.full((nv, 4), -1, np.int32)
    ww = np.zeros((nv, 4), np.float32)
    bfmt = _SIGNED[h.bone]
    layouts = {  # deform type -> (struct of its data, number of bones, weights given)
        0: struct.Struct(f"<{bfmt}"), 1: struct.Struct(f"<2{bfmt}f"), 2: struct.Struct(f"<4{bfmt}4f"),
        3: struct.Struct(f"<2{bfmt}f9f"), 4: struct.Struct(f"<4{bfmt}4f"),
    }
    sdef_rows: list[int] = []
    sdef_values: list[tuple] = []
    buf = r.data
    for i in range(nv):
        if r.left < head.size:
            raise r.fail(f"vertex {i} of {nv}: file truncated")
        vals = head.unpack_from(buf, r.pos)
        r.pos += head.size
        positions[i] = vals[0:3]
        normals[i] = vals[3:6]
        t = vals[-1]
        lay = layouts.get(t)
        if lay is None:
            raise r.fail(f"vertex {i}: deform type {t}, expected 0..4 (BDEF1, BDEF2, BDEF4, SDEF, QDEF)")
        if t == 4 and h.version < 2.1:
            raise r.fail(f"vertex {i}: QDEF weights in a PMX {h.version:g} file (QDEF is PMX 2.1)")
        if r.left < lay.size + 4:
            raise r.fail(f"vertex {i} of {nv}: file truncated in its weights")
        d = lay.unpack_from(buf, r.pos)
        r.pos += lay.size + 4  # + edge scale
        deform[i] = t
        if t == 0:
            wb[i, 0], ww[i, 0] = d[0], 1.0
        elif t in (1, 3):
            wb[i, :2] = d[:2]
            ww[i, :2] = (d[2], 1.0 - d[2])
            if t == 3:
                sdef_rows.append(i)
                sdef_values.append(d[3:12])
        else:
            wb[i] = d[:4]
            ww[i] = d[4:8]
    sdef = np.array(sdef_values, np.float32).reshape(-1, 3, 3)
    if nv and not (np.isfinite(positions).all() and np.isfinite(normals).all() and np.isfinite(ww).all()
                   and np.isfinite(sdef).all()):
        raise MMDFormatError(f"{name}: non-finite vertex position, normal, weight or SDEF parameter")

    nidx = r.count("face indices", h.vertex)
    if nidx % 3:
        raise r.fail(f"{nidx} face indices, expected a multiple of 3")
    vdt = {1: "u1", 2: "u2", 4: "i4"}[h.vertex]
    faces = r.array(vdt, (nidx // 3, 3), "face indices").astype(np.int64)
    check_indices(faces, nv, "face vertex", name, allow_minus_one=False)

    for _ in range(r.count("textures", 4)):
        text("texture path")
    nmat = r.count("materials", 8 + 4 * 16 + 2 * h.texture + 3 + 4 + 4)
    for _ in range(nmat):
        text("material name"), text("material English name")
        r.take(4 * 11 + 1 + 4 * 5, "material colours")
        r.take(2 * h.texture + 1, "material textures")
        toon_shared = r.int(1, "toon flag", signed=False)
        r.take(1 if toon_shared else h.texture, "toon texture")
        text("material memo")
        r.int(4, "material face count")

    nb = r.count("bones", 8 + 12 + h.bone + 4 + 2 + h.bone)
    bones = []
    for i in range(nb):
        bones.append(_read_bone(r, h, text, idx, i))
    for i, b in enumerate(bones):
        check_indices([b.parent, b.tail_bone, b.grant_parent], nb, f"bone {i} ({b.name}) parent/tail/grant", name)
        if b.ik is not None:
            check_indices([b.ik.target] + [link.bone for link in b.ik.links], nb, f"bone {i} ({b.name}) IK", name,
                          allow_minus_one=False)
        if b.parent == i:
            raise MMDFormatError(f"{name}: bone {i} ({b.name}) is its own parent")
    check_indices(wb, nb, "vertex weight bone", name)

    morph_names = []
    nm = r.count("morphs", 8 + 2 + 4)
    for _ in range(nm):
        morph_names.append(text("morph name"))
        text("morph English name")
        r.int(1, "morph panel")
        kind = r.int(1, "morph type", signed=False)
        if kind >= len(_MORPH_KINDS) or (kind >= 9 and h.version < 2.1):
            raise r.fail(f"morph type {kind}, expected 0..8 (PMX 2.0) or 0..10 (PMX 2.1)")
        size = {
            "group": h.morph + 4, "flip": h.morph + 4, "vertex": h.vertex + 12, "bone": h.bone + 28,
            "material": h.material + 1 + 112, "impulse": h.rigid + 1 + 24,
        }.get(_MORPH_KINDS[kind], h.vertex + 16)
        n = r.count("morph offsets", size)
        r.take(n * size, "morph offsets")

    for _ in range(r.count("display frames", 8 + 1 + 4)):
        text("display frame name"), text("display frame English name")
        r.int(1, "display frame flag")
        for _ in range(r.count("display frame items", 1 + min(h.bone, h.morph))):
            t = r.int(1, "display item type", signed=False)
            if t not in (0, 1):
                raise r.fail(f"display item type {t}, expected 0 (bone) or 1 (morph)")
            r.take(h.bone if t == 0 else h.morph, "display item")

    bodies = []
    nr = r.count("rigid bodies", 8 + h.bone + 1 + 2 + 1 + 36 + 20 + 1)
    for _ in range(nr):
        nm_, en = text("rigid body name"), text("rigid body English name")
        bone = idx(h.bone, "rigid body bone")
        group = r.int(1, "collision group", signed=False)
        mask = r.int(2, "collision mask", signed=False)
        shape = r.int(1, "shape", signed=False)
        v = r.floats(14, "rigid body geometry and physics")
        mode = r.int(1, "physics mode", signed=False)
        if shape > 2 or mode > 2 or group > 15:
            raise r.fail(f"rigid body {nm_!r}: shape {shape}, mode {mode}, group {group}; expected shape 0..2, "
                         "mode 0..2, group 0..15")
        bodies.append(MMDRigidBody(nm_, en, bone, group, mask, shape, v[0:3], v[3:6], v[6:9], float(v[9]),
                                   float(v[10]), float(v[11]), float(v[12]), float(v[13]), mode))
    check_indices([b.bone for b in bodies], nb, "rigid body bone", name)

    joints = []
    nj = r.count("joints", 8 + 1 + 2 * h.rigid + 96)
    for _ in range(nj):
        nm_, en = text("joint name"), text("joint English name")
        kind = r.int(1, "joint type", signed=False)
        if kind > 5:
            raise r.fail(f"joint {nm_!r}: type {kind}, expected 0..5")
        a, b = idx(h.rigid, "joint body A"), idx(h.rigid, "joint body B")
        v = r.floats(24, "joint frame, limits and springs")
        joints.append(MMDJoint(nm_, en, kind, a, b, v[0:3], v[3:6], v[6:9], v[9:12], v[12:15], v[15:18],
                               v[18:21], v[21:24]))
    check_indices([j.body_a for j in joints] + [j.body_b for j in joints], nr, "joint rigid body", name)

    return MMDModel(f"PMX {h.version:.1f}", model_name, model_name_en, comment, positions, normals, deform, wb, ww,
                    faces, bones, bodies, joints, nmat, nm, morph_names, np.asarray(sdef_rows, np.int64), sdef)


def _read_bone(r: BoundedReader, h: _Header, text, idx, i: int) -> MMDBone:
    name, name_en = text(f"bone {i} name"), text(f"bone {i} English name")
    pos = r.floats(3, f"bone {i} position")
    parent = idx(h.bone, f"bone {i} parent")
    layer = r.int(4, f"bone {i} layer")
    flags = r.int(2, f"bone {i} flags", signed=False)
    b = MMDBone(name, name_en, pos, parent, layer, flags)
    if flags & BONE_TAIL_IS_BONE:
        b.tail_bone = idx(h.bone, f"bone {i} tail")
    else:
        b.tail_offset = r.floats(3, f"bone {i} tail offset")
    if flags & (BONE_GRANT_ROTATION | BONE_GRANT_TRANSLATION):
        b.grant_parent = idx(h.bone, f"bone {i} grant parent")
        b.grant_ratio = r.float(f"bone {i} grant ratio")
    if flags & BONE_FIXED_AXIS:
        b.fixed_axis = r.floats(3, f"bone {i} fixed axis")
    if flags & BONE_LOCAL_AXIS:
        b.local_x = r.floats(3, f"bone {i} local x axis")
        b.local_z = r.floats(3, f"bone {i} local z axis")
    if flags & BONE_EXTERNAL_PARENT:
        r.int(4, f"bone {i} external parent key")
    if flags & BONE_IK:
        target = idx(h.bone, f"bone {i} IK target")
        loop = r.int(4, f"bone {i} IK loop count")
        limit = r.float(f"bone {i} IK unit angle")
        links = []
        for _ in range(r.count(f"bone {i} IK links", h.bone + 1)):
            lb = idx(h.bone, f"bone {i} IK link")
            has = r.int(1, f"bone {i} IK link limit flag", signed=False)
            if has > 1:
                raise r.fail(f"bone {i}: IK link limit flag {has}, expected 0 or 1")
            if has:
                lim = r.floats(6, f"bone {i} IK link limits")
                links.append(IKLink(lb, lim[:3], lim[3:]))
            else:
                links.append(IKLink(lb))
        if loop < 0 or loop > 10000:
            raise r.fail(f"bone {i}: IK loop count {loop}, expected 0..10000")
        b.ik = IKChain(target, loop, limit, links)
    return b
