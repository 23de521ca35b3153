"""Read VMD motion files (MikuMikuDance) with every value as stored.

Why not a library: pypmxvmd 2.7.2 reads VMD but turns rotations into Euler degrees (about 1e-4
lost per quaternion component); mmd-bone-tools reads only names. This reader keeps the
quaternions (float32 x, y, z, w as stored) and the 64 interpolation bytes exactly, checks every
count against the bytes left, and names the file in every error. Camera, light and shadow
sections are counted, not kept; the show/IK section (MMD 7.40+: per key a frame, the model's
visibility and an on/off flag per IK bone) is kept as ``ik_frames`` and ``ik_states``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimicbench.datagen.mmd.binary import BoundedReader
from mimicbench.datagen.mmd.errors import MMDFormatError

MAGIC_V2 = b"Vocaloid Motion Data 0002"
MAGIC_V1 = b"Vocaloid Motion Data file"
BONE_KEY = np.dtype([("name", "S15"), ("frame", "<u4"), ("position", "<f4", 3), ("rotation", "<f4", 4),
                     ("interpolation", "u1", 64)])
MORPH_KEY = np.dtype([("name", "S15"), ("frame", "<u4"), ("weight", "<f4")])
assert BONE_KEY.itemsize == 111 and MORPH_KEY.itemsize == 23


@dataclass
class VMDMotion:
    """Keys as stored, in file order.

    Bone keys: ``bone_names`` (n,) strings, ``frames`` (n,) int64 (30 fps), ``positions`` (n, 3)
    float32 translation from the rest pose in the parent's frame (MMD units, MMD frame),
    ``rotations`` (n, 4) float32 (x, y, z, w) local rotation from rest, ``interpolation`` (n, 64)
    uint8 (see :mod:`mimicbench.datagen.mmd.bezier`). Morph keys: ``morph_names``, ``morph_frames``,
    ``morph_weights``. Show/IK keys: ``ik_frames`` (m,) int64 and ``ik_states`` m dicts
    ``{IK bone name: enabled}`` (an IK bone a key does not name keeps its state)."""

    model_name: str
    bone_names: list[str]
    frames: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    interpolation: np.ndarray
    morph_names: list[str]
    morph_frames: np.ndarray
    morph_weights: np.ndarray
    num_camera_keys: int = 0
    num_light_keys: int = 0
    num_shadow_keys: int = 0
    ik_frames: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    ik_states: list = field(default_factory=list)  # per show/IK key: {IK bone name: on}

    @property
    def last_frame(self) -> int:
        return int(max(self.frames.max(initial=0), self.morph_frames.max(initial=0)))


def _names(raw: np.ndarray, r: BoundedReader, what: str) -> list[str]:
    out = []
    cache: dict[bytes, str] = {}
    for b in raw:
        if b not in cache:
            cut = bytes(b).split(b"\0", 1)[0]
            try:
                cache[b] = cut.decode("cp932")
            except UnicodeDecodeError:
                try:  # a name cut at 15 bytes can split a two-byte character
                    cache[b] = cut[:-1].decode("cp932")
                except UnicodeDecodeError as e:
                    raise MMDFormatError(f"{r.name}: {what} {bytes(b)!r} is not valid Shift-JIS ({e.reason})") from None
        out.append(cache[b])
    return out


def read_vmd(path) -> VMDMotion:
    """Read a VMD file; raises :class:`MMDFormatError` naming the file for anything malformed."""
    path = Path(path)
    return parse_vmd(path.read_bytes(), str(path))


def parse_vmd(data: bytes, name: str = "<vmd>") -> VMDMotion:
    """Parse VMD bytes (see :func:`read_vmd`); ``name`` is used in errors."""
    r = BoundedReader(data, name)
    sig = bytes(r.take(30, "signature"))
    if sig.startswith(MAGIC_V2):
        model_name = r.fixed_text(20, "model name")
    elif sig.startswith(MAGIC_V1):
        model_name = r.fixed_text(10, "model name")
    else:
        raise MMDFormatError(f"{name}: wrong magic {sig[:25]!r}, expected {MAGIC_V2!r} (not a VMD file)")
    n = r.count("bone keys", BONE_KEY.itemsize)
    bones = np.frombuffer(r.take(n * BONE_KEY.itemsize, "bone keys"), BONE_KEY)
    for column in ("position", "rotation"):
        if not np.isfinite(bones[column]).all():
            raise MMDFormatError(f"{name}: non-finite bone key {column}")
    norms = np.linalg.norm(bones["rotation"].astype(np.float64), axis=1)
    if n and (norms < 1e-3).any():
        raise MMDFormatError(f"{name}: bone key {int(np.argmax(norms < 1e-3))} has a zero rotation quaternion")
    if (bones["interpolation"][:, :16] > 127).any():
        raise MMDFormatError(f"{name}: bone key interpolation control point above 127")
    morphs = np.zeros(0, MORPH_KEY)
    cams = lights = 0
    if r.left:
        m = r.count("morph keys", MORPH_KEY.itemsize)
        morphs = np.frombuffer(r.take(m * MORPH_KEY.itemsize, "morph keys"), MORPH_KEY)
        if not np.isfinite(morphs["weight"]).all():
            raise MMDFormatError(f"{name}: non-finite morph key weight")
    if r.left:
        cams = r.count("camera keys", 61)
        r.take(61 * cams, "camera keys")
    if r.left:
        lights = r.count("light keys", 28)
        r.take(28 * lights, "light keys")
    shadows = 0
    ik_frames: list[int] = []
    ik_states: list[dict] = []
    if r.left:
        shadows = r.count("self-shadow keys", 9)
        r.take(9 * shadows, "self-shadow keys")
    if r.left:
        for k in range(r.count("show/IK keys", 9)):
            ik_frames.append(r.int(4, f"show/IK key {k} frame", signed=False))
            r.int(1, f"show/IK key {k} visibility", signed=False)
            state = {}
            for e in range(r.count(f"IK entries of show/IK key {k}", 21)):
                bone = r.fixed_text(20, f"show/IK key {k} IK bone name {e}")
                flag = r.int(1, f"show/IK key {k} IK flag {e}", signed=False)
                if flag > 1:
                    raise MMDFormatError(f"{name}: show/IK key {k}: IK flag {flag} for {bone!r}, expected 0 (off) "
                                         f"or 1 (on)")
                state[bone] = bool(flag)
            ik_states.append(state)
    return VMDMotion(model_name, _names(bones["name"], r, "bone name"), bones["frame"].astype(np.int64),
                     bones["position"].copy(), bones["rotation"].copy(), bones["interpolation"].copy(),
                     _names(morphs["name"], r, "morph name"), morphs["frame"].astype(np.int64),
                     morphs["weight"].astype(np.float32), cams, lights, shadows,
                     np.asarray(ik_frames, np.int64), ik_states)
