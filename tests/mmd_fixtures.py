"""Small MMD files written field by field from the PMX 2.0/2.1 and PMD specifications, for tests.

These writers are deliberately independent of :mod:`mimicbench.datagen.mmd` (only ``struct``), so a
reader bug is not mirrored by the fixture."""
from __future__ import annotations

import struct


SDEF_C_R0_R1 = (0.5, 1.0, 0.25, 1.0, 1.0, -1.0, 0.0, 2.0, 2.0)  # the SDEF vertex's C, R0, R1 (MMD units)


def _text(s: str, enc: str) -> bytes:
    b = s.encode(enc)
    return struct.pack("<i", len(b)) + b


def pmx_bytes(version: float = 2.0, encoding: int = 0, extra_uv: int = 0, qdef: bool = False,
              bad_index: bool = False, nan: bool = False) -> bytes:
    """A 3-bone, 4-vertex, 2-triangle PMX with one IK bone, a grant bone, 2 rigid bodies, 1 joint.

    Bones: 0 センター (root, at y=10), 1 左足 (parent 0, at (1, 8, 0)), 2 左足ＩＫ (parent 0, IK on
    bone 1, link 1 limited to x in [-1, 0]), plus bone 1 grants rotation 0.5 from bone 0 (for the
    test). Vertices: BDEF1, BDEF2 (0.25), BDEF4 (0.5, 0.5, 0, 0), and SDEF or QDEF."""
    enc = "utf-16-le" if encoding == 0 else "utf-8"
    t = lambda s: _text(s, enc)  # noqa: E731
    out = b"PMX " + struct.pack("<f", version) + bytes([8, encoding, extra_uv, 1, 1, 1, 1, 1, 1])
    out += t("テスト") + t("test") + t("comment") + t("")
    verts = [
        ((0, 0, 0), 0, [0]),
        ((1, 0, -1), 1, [1, 0, 0.25]),
        ((0, 1, 0), 2, [0, 1, 2, 0, 0.5, 0.5, 0.0, 0.0]),
        ((1, 1, float("nan") if nan else 0.5), 4 if qdef else 3, None),
    ]
    out += struct.pack("<i", len(verts))
    for pos, kind, data in verts:
        out += struct.pack("<8f", *pos, 0, 0, -1, 0, 0) + struct.pack(f"<{4 * extra_uv}f", *([0.5] * 4 * extra_uv))
        out += bytes([kind])
        if kind == 0:
            out += struct.pack("<b", data[0])
        elif kind == 1:
            out += struct.pack("<2bf", *data)
        elif kind == 2:
            out += struct.pack("<4b4f", *data)
        elif kind == 3:
            out += struct.pack("<2bf9f", 1, 2, 0.75, *SDEF_C_R0_R1)
        else:
            out += struct.pack("<4b4f", 1, 2, -1, -1, 0.75, 0.25, 0, 0)
        out += struct.pack("<f", 1.0)
    faces = [0, 1, 2, 1, 3, 9 if bad_index else 2]
    out += struct.pack("<i", len(faces)) + bytes(faces)
    out += struct.pack("<i", 0)  # textures
    out += struct.pack("<i", 1) + t("mat") + t("mat") + struct.pack("<11fB5f", *([1.0] * 11), 0, *([0.0] * 5))
    out += struct.pack("<bbBBb", -1, -1, 0, 1, 0) + t("") + struct.pack("<i", 6)
    out += struct.pack("<i", 3)
    # bone 0: root, tail offset, rotatable|movable|visible|operable
    out += t("センター") + t("center") + struct.pack("<3fbiH", 0, 10, 0, -1, 0, 0x001E) + struct.pack("<3f", 0, 1, 0)
    # bone 1: child, tail offset, grant rotation 0.5 from bone 0
    out += t("左足") + t("leg_L") + struct.pack("<3fbiH", 1, 8, 0, 0, 0, 0x011A) + struct.pack("<3f", 0, -4, 0)
    out += struct.pack("<bf", 0, 0.5)
    # bone 2: IK bone, tail offset, IK target 1, loop 40, unit angle 2, one limited link
    out += t("左足ＩＫ") + t("leg IK_L") + struct.pack("<3fbiH", 1, 4, 0, 0, 1, 0x003E) + struct.pack("<3f", 0, 0, 1)
    out += struct.pack("<bifi", 1, 40, 2.0, 1) + struct.pack("<bB6f", 1, 1, -1, 0, 0, 0, 0, 0)
    out += struct.pack("<i", 1) + t("あ") + t("a") + bytes([3, 1]) + struct.pack("<i", 1) + struct.pack("<b3f", 0, 0, 0.1, 0)
    out += struct.pack("<i", 1) + t("Root") + t("Root") + bytes([1]) + struct.pack("<i", 1) + bytes([0, 0])
    out += struct.pack("<i", 2)
    out += t("体") + t("body") + struct.pack("<bBHB", 0, 0, 0xFFFE, 0) + struct.pack("<9f", 1, 0, 0, 0, 10, 0, 0, 0, 0)
    out += struct.pack("<5fB", 1, 0.5, 0.5, 0, 0.5, 0)
    out += t("髪") + t("hair") + struct.pack("<bBHB", 1, 3, 0xFFFF, 2) + struct.pack("<9f", 0.5, 2, 0, 1, 8, -2, 0.1, 0.2, 0.3)
    out += struct.pack("<5fB", 2, 0.9, 0.8, 0.1, 0.4, 1)
    out += struct.pack("<i", 1) + t("j") + t("j") + bytes([0]) + struct.pack("<bb", 0, 1)
    out += struct.pack("<24f", 1, 9, -1, 0.1, 0.2, 0.3, -1, -2, -3, 1, 2, 5, -0.1, -0.2, -0.3, 0.4, 0.5, 0.6,
                       10, 20, 30, 1, 2, 3)
    return out


def pmd_bytes() -> bytes:
    """A 2-bone PMD (センター, 左ひざ with an IK bone 左足ＩＫ), 3 vertices, 1 triangle, one rigid body
    with bone index -1 (offset from bone 0) and one on bone 1, one joint, English names."""
    name = lambda s, n: s.encode("cp932").ljust(n, b"\0")  # noqa: E731
    out = b"Pmd" + struct.pack("<f", 1.0) + name("pmdtest", 20) + name("c", 256)
    out += struct.pack("<I", 3)
    for pos, b0, b1, w in (((0, 0, 0), 0, 1, 100), ((1, 0, 0), 0, 1, 30), ((0, 1, 0), 0, 1, 0)):
        out += struct.pack("<8f2HBB", *pos, 0, 0, -1, 0, 0, b0, b1, w, 0)
    out += struct.pack("<I", 3) + struct.pack("<3H", 0, 1, 2)
    out += struct.pack("<I", 1) + struct.pack("<3ff f3f3fBBI", 1, 1, 1, 1, 5, 0, 0, 0, 0, 0, 0, 0, 0, 3) + name("", 20)
    out += struct.pack("<H", 3)
    out += name("センター", 20) + struct.pack("<HHBH3f", 0xFFFF, 1, 1, 0, 0, 10, 0)
    out += name("左ひざ", 20) + struct.pack("<HHBH3f", 0, 0, 0, 0, 1, 5, 0)
    out += name("左足ＩＫ", 20) + struct.pack("<HHBH3f", 0, 0, 2, 1, 1, 1, 0)
    out += struct.pack("<H", 1) + struct.pack("<HHBHf", 2, 1, 1, 40, 0.5) + struct.pack("<H", 1)
    out += struct.pack("<H", 0) + bytes([0]) + bytes([0]) + struct.pack("<I", 0)
    out += bytes([1]) + name("pmd test", 20) + name("", 256) + name("center", 20) + name("knee_L", 20) + name("leg IK_L", 20)
    out += b"\0" * 1000
    out += struct.pack("<I", 2)
    out += name("体", 20) + struct.pack("<HBHB", 0xFFFF, 0, 0xFFFF, 0) + struct.pack("<9f", 1, 0, 0, 0, 1, 0, 0, 0, 0)
    out += struct.pack("<5fB", 1, 0.5, 0.5, 0, 0.5, 0)
    out += name("髪", 20) + struct.pack("<HBHB", 1, 2, 0xFFFB, 2) + struct.pack("<9f", 0.5, 2, 0, 0, -1, 0, 0, 0, 0)
    out += struct.pack("<5fB", 2, 0.9, 0.8, 0.1, 0.4, 1)
    out += struct.pack("<I", 1) + name("j", 20) + struct.pack("<ii", 0, 1) + struct.pack("<24f", *range(24))
    return out


def vmd_bytes(keys, morphs=(), model: str = "model", ik=None) -> bytes:
    """A VMD (version 0002) with bone keys ``(name, frame, (x, y, z), (qx, qy, qz, qw), curves)``,
    ``curves`` a dict channel index (0 x, 1 y, 2 z, 3 rotation) -> (x1, y1, x2, y2) bytes 0..127
    (unlisted channels linear: 20, 20, 107, 107), laid out as MMD writes them (the first 16 bytes:
    x1 of the four channels, y1, x2, y2; the other 48 bytes MMD's shifted copies). ``ik``: show/IK
    keys ``(frame, shown, [(IK bone name, on), ...])`` written after the empty camera, light and
    self-shadow sections (none: the file ends after the self-shadow count)."""
    name = lambda s, n: s.encode("cp932")[:n].ljust(n, b"\0")  # noqa: E731
    out = b"Vocaloid Motion Data 0002".ljust(30, b"\0") + name(model, 20) + struct.pack("<I", len(keys))
    for bone, frame, pos, rot, curves in keys:
        cp = [curves.get(c, (20, 20, 107, 107)) for c in range(4)]
        row = bytes(cp[c][j] for j in range(4) for c in range(4))
        ip = row + row[1:] + b"\0" + row[2:] + b"\0\0" + row[3:] + b"\0\0\0"
        out += name(bone, 15) + struct.pack("<I3f4f", frame, *pos, *rot) + ip[:64]
    out += struct.pack("<I", len(morphs))
    for morph, frame, weight in morphs:
        out += name(morph, 15) + struct.pack("<If", frame, weight)
    out += struct.pack("<III", 0, 0, 0)
    if ik is not None:
        out += struct.pack("<I", len(ik))
        for frame, shown, states in ik:
            out += struct.pack("<IBI", frame, shown, len(states))
            for bone, on in states:
                out += name(bone, 20) + struct.pack("<B", on)
    return out
