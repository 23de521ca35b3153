"""Make test variants of a GLB file (numpy and the standard library only): re-timed keys that fall
between the 24 fps samples, STEP and CUBICSPLINE samplers, an animated non-uniform bone scale, and
a clip that animates no bone. The variants are valid glTF 2.0, so the reference evaluator
(:mod:`tests.gltf_reference`) and Blender read the same file."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


def read_glb(path) -> tuple[dict, bytearray]:
    data = Path(path).read_bytes()
    offset, doc, blob = 12, None, bytearray()
    while offset < len(data):
        size, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8: offset + 8 + size]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == 0x004E4942:
            blob = bytearray(chunk)
        offset += 8 + size
    return doc, blob


def write_glb(path, doc: dict, blob: bytearray) -> Path:
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc).encode("utf-8")
    text += b" " * (-len(text) % 4)
    blob = bytes(blob) + b"\0" * (-len(blob) % 4)
    out = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob))
    out += struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    Path(path).write_bytes(out)
    return Path(path)


def add_accessor(doc: dict, blob: bytearray, values: np.ndarray, dtype=np.float32, kind: str | None = None) -> int:
    """Append ``values`` (count, width) as a new accessor of ``dtype`` (float32 or uint8) and glTF
    type ``kind`` (default from the width; ``MAT4`` for (count, 16) column-major matrices)."""
    values = np.ascontiguousarray(values, dtype).reshape(len(values), -1)
    blob.extend(b"\0" * (-len(blob) % 4))
    doc.setdefault("bufferViews", []).append({"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes})
    blob.extend(values.tobytes())
    acc = {"bufferView": len(doc["bufferViews"]) - 1, "componentType": {np.float32: 5126, np.uint8: 5121}[dtype],
           "count": len(values), "type": kind or _TYPES[values.shape[1]]}
    if values.shape[1] == 1 and dtype is np.float32:
        acc["min"], acc["max"] = [float(values.min())], [float(values.max())]
    doc["accessors"].append(acc)
    return len(doc["accessors"]) - 1


def _read(doc, blob, index) -> np.ndarray:
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[a["type"]]
    if a["componentType"] != 5126 or view.get("byteStride", 4 * width) != 4 * width:
        raise ValueError("this helper only edits tightly packed float32 accessors")
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    return np.frombuffer(bytes(blob[start: start + 4 * width * a["count"]]), np.float32).reshape(-1, width).astype(np.float64)


def make_variant(src, dst, time_scale: float = 1.3, time_offset: float = 0.01, scale_node: str | None = None,
                 scale_to=(1.0, 0.8, 1.15), boneless_node: str | None = None) -> Path:
    """Write a variant of ``src``: every key time becomes ``t * time_scale + time_offset``; sampler
    i becomes LINEAR, STEP or CUBICSPLINE by i mod 3 (cubic tangents from central differences);
    ``scale_node`` gets a scale channel in every clip (1 -> ``scale_to`` -> 1 over the clip);
    ``boneless_node`` gets an extra clip ``NoBones`` that moves only that (non-joint) node."""
    doc, blob = read_glb(src)
    names = [n.get("name") for n in doc["nodes"]]
    for anim in doc.get("animations", []):
        t_all = []
        for i, s in enumerate(anim["samplers"]):
            t = _read(doc, blob, s["input"])[:, 0] * time_scale + time_offset
            v = _read(doc, blob, s["output"])
            mode = ("LINEAR", "STEP", "CUBICSPLINE")[i % 3] if len(t) > 2 and len(v) == len(t) else "LINEAR"
            if mode == "CUBICSPLINE":  # central differences, one-sided at the ends (units per second)
                slope = np.empty_like(v)
                slope[1:-1] = (v[2:] - v[:-2]) / (t[2:] - t[:-2])[:, None]
                slope[0] = (v[1] - v[0]) / (t[1] - t[0])
                slope[-1] = (v[-1] - v[-2]) / (t[-1] - t[-2])
                v = np.stack([slope, v, slope], axis=1).reshape(-1, v.shape[1])
            s["input"] = add_accessor(doc, blob, t[:, None])
            s["output"] = add_accessor(doc, blob, v)
            s["interpolation"] = mode
            t_all.append(t)
        if scale_node is not None:
            t0, t1 = min(t.min() for t in t_all), max(t.max() for t in t_all)
            times = np.linspace(t0, t1, 5)
            target = np.asarray(scale_to, np.float64)
            vals = np.array([np.ones(3), 0.5 * (1 + target), target, 0.5 * (1 + target), np.ones(3)])
            anim["samplers"].append({"input": add_accessor(doc, blob, times[:, None]),
                                     "output": add_accessor(doc, blob, vals), "interpolation": "LINEAR"})
            anim["channels"].append({"sampler": len(anim["samplers"]) - 1,
                                     "target": {"node": names.index(scale_node), "path": "scale"}})
    if boneless_node is not None:
        node = doc["nodes"][names.index(boneless_node)]
        base = np.array(node.get("translation", [0, 0, 0]), np.float64)
        times = np.array([0.0, 0.5, 1.0])
        vals = np.array([base, base + [0, 0.1, 0], base])
        doc["animations"].append({"name": "NoBones", "samplers": [
            {"input": add_accessor(doc, blob, times[:, None]), "output": add_accessor(doc, blob, vals)}],
            "channels": [{"sampler": 0, "target": {"node": names.index(boneless_node), "path": "translation"}}]})
    return write_glb(dst, doc, blob)
