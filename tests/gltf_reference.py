"""A small glTF 2.0 evaluator written from the specification (numpy only): the independent
reference the ingest tests compare with. It never imports Blender or mimicbench.

What it does (glTF 2.0 spec sections in brackets):
- GLB container: 12-byte header, a JSON chunk, an optional BIN chunk [4.4 Binary glTF Layout].
- Accessors: bufferView offset and stride, every component type, ``normalized`` integers [3.6].
- Nodes: ``matrix`` or TRS (default T 0, R (0,0,0,1) x,y,z,w, S 1), world = parent world @ local [3.5].
- Animation samplers: LINEAR (lerp; slerp on the shortest path for rotations), STEP and
  CUBICSPLINE (Hermite with in/out tangents scaled by the key interval, rotations normalised);
  times before the first key take the first value and after the last the last [3.11, Appendix C].
  Nodes and paths a clip does not target keep their default TRS.
- Skins: joint matrix = world(joint) @ inverseBindMatrix (identity when absent); a skinned mesh's
  own node transform is ignored; every JOINTS_n/WEIGHTS_n set is used [3.7.3]. Unskinned meshes
  take their node's world matrix. Morph targets are left at zero weight (the dataset stores the
  basis shape).

Coordinates are glTF's (metres, Y up, +Z forward), which is the dataset frame.
"""
from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


@dataclass
class Primitive:
    """One mesh primitive placed in the scene: ``node`` (the node that instantiates the mesh),
    ``positions`` (V, 3), ``joints`` (V, J) skin joint indices, ``weights`` (V, J), ``skin`` index or None."""

    node: int
    mesh: int
    index: int
    positions: np.ndarray
    joints: np.ndarray | None
    weights: np.ndarray | None
    skin: int | None


class GltfReference:
    """A parsed .glb file that evaluates node transforms and skinned vertices at any clip time."""

    def __init__(self, path: str | Path):
        data = Path(path).read_bytes()
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        if magic != b"glTF" or version != 2:
            raise ValueError(f"{path}: expected a GLB 2.0 file (magic 'glTF', version 2)")
        offset, self.bin = 12, b""
        while offset < length:
            size, kind = struct.unpack_from("<II", data, offset)
            chunk = data[offset + 8: offset + 8 + size]
            if kind == 0x4E4F534A:  # JSON
                self.json = json.loads(chunk.decode("utf-8"))
            elif kind == 0x004E4942:  # BIN
                self.bin = chunk
            offset += 8 + size
        g = self.json
        self.nodes = g.get("nodes", [])
        self.parent = np.full(len(self.nodes), -1)
        for i, n in enumerate(self.nodes):
            for c in n.get("children", []):
                self.parent[c] = i
        self.skins = g.get("skins", [])
        self.animations = g.get("animations", [])

    # --- binary data -------------------------------------------------------------------------
    def accessor(self, index: int) -> np.ndarray:
        """Accessor ``index`` as float64 (count, width) (normalised integers mapped to [0,1] / [-1,1])."""
        a = self.json["accessors"][index]
        dtype = np.dtype(_COMPONENT[a["componentType"]])
        width = _WIDTH[a["type"]]
        out = np.zeros((a["count"], width), np.float64)
        if "bufferView" in a:
            view = self.json["bufferViews"][a["bufferView"]]
            if view.get("buffer", 0) != 0:
                raise ValueError("only the GLB's own buffer is supported")
            start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
            stride = view.get("byteStride", 0) or dtype.itemsize * width
            raw = np.frombuffer(self.bin, np.uint8, count=stride * (a["count"] - 1) + dtype.itemsize * width,
                                offset=start)
            rows = np.lib.stride_tricks.as_strided(raw, (a["count"], dtype.itemsize * width), (stride, 1))
            out = np.ascontiguousarray(rows).view(dtype).reshape(a["count"], width).astype(np.float64)
            if a.get("normalized"):
                info = np.iinfo(dtype)
                out = np.maximum(out / info.max, -1.0) if info.min < 0 else out / info.max
        if "sparse" in a:
            raise ValueError("sparse accessors are not supported by this reference")
        return out

    # --- nodes and animation ---------------------------------------------------------------------
    def default_trs(self, node: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | np.ndarray:
        n = self.nodes[node]
        if "matrix" in n:
            return np.array(n["matrix"], np.float64).reshape(4, 4).T  # column-major
        return (np.array(n.get("translation", [0, 0, 0]), np.float64),
                np.array(n.get("rotation", [0, 0, 0, 1]), np.float64),
                np.array(n.get("scale", [1, 1, 1]), np.float64))

    def clip_range(self, clip: int) -> tuple[float, float]:
        """(t0, t1) seconds: the earliest and latest key time of any channel of the clip."""
        anim = self.animations[clip]
        times = [self.accessor(s["input"])[:, 0] for s in anim["samplers"]]
        return float(min(t.min() for t in times)), float(max(t.max() for t in times))

    def sample(self, clip: int | None, t: float) -> list:
        """Per node the local transform at time ``t`` of clip ``clip`` (None: every node at its default)."""
        local = [self.default_trs(i) for i in range(len(self.nodes))]
        local = [list(x) if isinstance(x, tuple) else x for x in local]
        if clip is None:
            return local
        anim = self.animations[clip]
        for ch in anim["channels"]:
            node, path = ch["target"].get("node"), ch["target"]["path"]
            if node is None or path == "weights":
                continue
            if isinstance(local[node], np.ndarray):
                raise ValueError(f"node {node} has a matrix and is animated: not valid glTF")
            s = anim["samplers"][ch["sampler"]]
            value = _interpolate(self.accessor(s["input"])[:, 0], self.accessor(s["output"]),
                                 s.get("interpolation", "LINEAR"), t, path == "rotation")
            local[node][{"translation": 0, "rotation": 1, "scale": 2}[path]] = value
        return local

    def world_matrices(self, local: list) -> np.ndarray:
        """(nodes, 4, 4) world matrices from per-node local transforms."""
        mats = np.array([_trs_matrix(*x) if isinstance(x, list) else x for x in local])
        world = np.zeros_like(mats)
        done = np.zeros(len(mats), bool)

        def visit(i):
            if not done[i]:
                p = self.parent[i]
                world[i] = mats[i] if p < 0 else visit(p) @ mats[i]
                done[i] = True
            return world[i]

        for i in range(len(mats)):
            visit(i)
        return world

    # --- meshes --------------------------------------------------------------------------------
    def primitives(self) -> list[Primitive]:
        """Every mesh primitive instantiated by a node of the scene."""
        out = []
        for ni, n in enumerate(self.nodes):
            if "mesh" not in n:
                continue
            for pi, p in enumerate(self.json["meshes"][n["mesh"]]["primitives"]):
                attrs = p["attributes"]
                joints, weights = [], []
                k = 0
                while f"JOINTS_{k}" in attrs:
                    joints.append(self.accessor(attrs[f"JOINTS_{k}"]).astype(np.int64))
                    weights.append(self.accessor(attrs[f"WEIGHTS_{k}"]))
                    k += 1
                skinned = "skin" in n and joints
                out.append(Primitive(ni, n["mesh"], pi, self.accessor(attrs["POSITION"]),
                                     np.concatenate(joints, 1) if skinned else None,
                                     np.concatenate(weights, 1) if skinned else None,
                                     n["skin"] if skinned else None))
        return out

    def vertices(self, clip: int | None, t: float = 0.0) -> np.ndarray:
        """(V, 3) every primitive's vertices (concatenated in :meth:`primitives` order) at time ``t``."""
        world = self.world_matrices(self.sample(clip, t))
        chunks = []
        for p in self.primitives():
            homo = np.concatenate([p.positions, np.ones((len(p.positions), 1))], axis=1)
            if p.skin is None:
                chunks.append(homo @ world[p.node].T)
                continue
            skin = self.skins[p.skin]
            ibm = (self.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
                   if "inverseBindMatrices" in skin else np.tile(np.eye(4), (len(skin["joints"]), 1, 1)))
            joint_mats = world[skin["joints"]] @ ibm  # (J, 4, 4)
            w = p.weights / np.maximum(p.weights.sum(axis=1, keepdims=True), 1e-12)
            blended = np.einsum("vj,vjab->vab", w, joint_mats[p.joints])
            chunks.append(np.einsum("vab,vb->va", blended, homo))
        return np.concatenate(chunks)[:, :3] if chunks else np.zeros((0, 3))


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """3x3 rotation of a glTF quaternion (x, y, z, w)."""
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _trs_matrix(t, r, s) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = quat_matrix(np.asarray(r)) * np.asarray(s)[None, :]
    m[:3, 3] = t
    return m


def slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions on the shorter arc (glTF Appendix C)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    d = float(a @ b)
    if d < 0:
        b, d = -b, -d
    if d > 0.9995:
        q = a + u * (b - a)
        return q / np.linalg.norm(q)
    theta = np.arccos(d)
    return (np.sin((1 - u) * theta) * a + np.sin(u * theta) * b) / np.sin(theta)


def _interpolate(times: np.ndarray, values: np.ndarray, mode: str, t: float, rotation: bool) -> np.ndarray:
    """Sampler value at time ``t``; ``values`` (keys, width), or (3*keys, width) for CUBICSPLINE."""
    cubic = mode == "CUBICSPLINE"
    if cubic:
        values = values.reshape(len(times), 3, -1)  # in-tangent, value, out-tangent
        point = values[:, 1]
    else:
        point = values
    if t <= times[0]:
        v = point[0]
    elif t >= times[-1]:
        v = point[-1]
    else:
        k = int(np.searchsorted(times, t, side="right") - 1)
        td = times[k + 1] - times[k]
        u = (t - times[k]) / td
        if mode == "STEP":
            v = point[k]
        elif cubic:
            h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
            h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
            v = h00 * point[k] + h10 * td * values[k, 2] + h01 * point[k + 1] + h11 * td * values[k + 1, 0]
        elif rotation:
            v = slerp(point[k], point[k + 1], u)
        else:
            v = (1 - u) * point[k] + u * point[k + 1]
    v = np.array(v, np.float64)
    return v / np.linalg.norm(v) if rotation else v
