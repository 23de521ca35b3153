"""Write a character (and its rigid bodies and joints) as a PMX 2.0 file: the inverse of
:mod:`mimicbench.datagen.mmd.records` and :mod:`mimicbench.datagen.mmd.physics` (metres -> MMD units, z mirrored back,
faces reversed back, Euler angles R = Ry Rx Rz, limits swapped and negated back).

Weights keep each vertex's 4 largest influences (PMX's BDEF4 limit), renormalised; BDEF1 or
BDEF2 when a vertex has 1 or 2. UTF-16LE text, 4-byte indices, no materials beyond one, no
morphs. Used for ``zoo`` characters and round-trip tests.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from mimicbench.datagen.mmd import frame
from mimicbench.geometry.quaternion import quat_to_matrix
from mimicbench.schemas.joint import KINDS
from mimicbench.schemas.rigid_body import MODES, SHAPES

_ENC = "utf-16-le"


def _text(s: str) -> bytes:
    b = s.encode(_ENC)
    return struct.pack("<i", len(b)) + b


def euler_yxz(m: np.ndarray) -> np.ndarray:
    """(rx, ry, rz) with m = Ry(ry) Rx(rx) Rz(rz) (MMD's rigid-body order)."""
    rx = np.arcsin(np.clip(-m[1, 2], -1.0, 1.0))
    return np.array([rx, np.arctan2(m[0, 2], m[2, 2]), np.arctan2(m[1, 0], m[1, 1])])


def _mmd_euler(q_dataset: np.ndarray) -> np.ndarray:
    """Dataset-frame quaternion -> MMD-frame Euler (rx, ry, rz)."""
    return frame.euler(euler_yxz(quat_to_matrix(np.asarray(q_dataset, np.float64))))


def pmx_bytes(character, bodies=(), joints=(), scale: float = frame.MMD_UNIT_METRES) -> bytes:
    """The PMX 2.0 bytes of ``character`` (a CharacterRecord) with ``bodies``/``joints`` records."""
    inv = 1.0 / scale
    out = b"PMX " + struct.pack("<f", 2.0) + bytes([8, 0, 0, 4, 4, 4, 4, 4, 4])
    out += _text(character.character_id) + _text(character.character_id) + _text(character.source) + _text("")
    verts = frame.point(character.vertices, inv)  # mirror back; scale by 1/scale
    wi = np.asarray(character.weight_indices)
    wv = np.asarray(character.weight_values, np.float64)
    order = np.argsort(-wv, axis=1, kind="stable")[:, :4]
    top_i = np.take_along_axis(wi, order, axis=1)
    top_w = np.take_along_axis(wv, order, axis=1)
    top_w = top_w / top_w.sum(axis=1, keepdims=True)
    out += struct.pack("<i", len(verts))
    body = bytearray()
    for p, idx, w in zip(verts, top_i, top_w):
        body += struct.pack("<8f", *p, 0.0, 1.0, 0.0, 0.0, 0.0)
        n = int((w > 0).sum())
        if n <= 1:
            body += struct.pack("<Bi", 0, idx[0])
        elif n == 2:
            body += struct.pack("<B2if", 1, idx[0], idx[1], w[0])
        else:
            body += struct.pack("<B4i4f", 2, *idx, *w)
        body += struct.pack("<f", 1.0)
    out += bytes(body)
    faces = np.asarray(character.faces, np.int32)[:, [0, 2, 1]]
    out += struct.pack("<i", faces.size) + faces.astype("<i4").tobytes()
    out += struct.pack("<i", 0)  # textures
    out += struct.pack("<i", 1) + _text("material") + _text("material")
    out += struct.pack("<11fB5f", 1, 1, 1, 1, 0, 0, 0, 0, 0.5, 0.5, 0.5, 0, 0, 0, 0, 1, 0)
    out += struct.pack("<iiBB", -1, -1, 0, 1) + bytes([0]) + _text("") + struct.pack("<i", faces.size)
    heads = frame.point(character.keypoints, inv)
    out += struct.pack("<i", len(heads))
    for name, head, parent in zip(character.bone_names, heads, character.parents):
        out += _text(name) + _text("") + struct.pack("<3fiiH", *head, int(parent), 0, 0x001E) + struct.pack("<3f", 0, 0, 0)
    out += struct.pack("<i", 0)  # morphs
    out += struct.pack("<i", 0)  # display frames
    out += struct.pack("<i", len(bodies))
    for b in bodies:
        size = np.asarray(b.size, np.float64) * inv
        out += _text(b.name) + _text(b.name_en) + struct.pack("<iBHB", int(b.bone), b.collision_group,
                                                              b.collision_mask, SHAPES.index(b.shape))
        out += struct.pack("<9f", *size, *frame.point(b.position, inv), *_mmd_euler(b.rotation))
        out += struct.pack("<5fB", b.mass, b.linear_damping, b.angular_damping, b.restitution, b.friction,
                           MODES.index(b.mode))
    out += struct.pack("<i", len(joints))
    for j in joints:
        tlo, thi = frame.interval(np.asarray(j.translation_min) * inv, np.asarray(j.translation_max) * inv, frame.MIRROR)
        rlo, rhi = frame.interval(j.rotation_min, j.rotation_max, frame.ANGLE_MIRROR)
        out += _text(j.name) + _text(j.name_en) + struct.pack("<Bii", KINDS.index(j.kind), j.body_a, j.body_b)
        out += struct.pack("<24f", *frame.point(j.position, inv), *_mmd_euler(j.rotation), *tlo, *thi, *rlo, *rhi,
                           *j.spring_translation, *j.spring_rotation)
    return out


def write_pmx(path, character, bodies=(), joints=(), scale: float = frame.MMD_UNIT_METRES) -> Path:
    """Write :func:`pmx_bytes` to ``path`` (written whole, then renamed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(pmx_bytes(character, bodies, joints, scale))
    tmp.replace(path)
    return path
