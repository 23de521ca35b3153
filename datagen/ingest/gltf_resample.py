"""Resample a glTF file's animations at the dataset's frame times, by the glTF 2.0 specification,
before Blender imports it.

Blender's glTF importer keeps the file's keys but not its interpolation: LINEAR rotations become
per-component linear curves (not slerp), CUBICSPLINE tangents are dropped (automatic Bezier
handles instead), and a STEP key that lands on a sample is read on either side. So every clip is
first evaluated here at its own frame times ``t0 + f / fps`` (LINEAR: lerp, slerp on the shorter
arc for rotations; STEP; CUBICSPLINE: Hermite with the key interval times the tangents, rotations
normalised; before the first key the first value, after the last the last; glTF 2.0 section
3.11 and Appendix C), and written as a LINEAR clip with a key at every frame. Blender then only
reads keys. Morph-target weights are dropped (the dataset stores the basis shape), and so are
materials and images, which ingest does not use. The result is a self-contained GLB.
NumPy and the standard library only (this runs inside the Blender child process).
"""
from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_FRAME_EPS = 1e-3  # frames: a clip spanning n - 1 + 0.999 frames has n samples


def load_gltf(path: str | Path) -> tuple[dict, list[bytes]]:
    """(JSON document, bytes of each buffer) of a .glb or .gltf file (``data:`` or relative URIs)."""
    from mimicbench.datagen.ingest.uris import gltf_document, resource_uris

    path = Path(path)
    doc, blob = gltf_document(path)  # the one GLB chunk parser, shared with the URI check
    blob = blob or b""
    resource_uris(doc, str(path))  # buffers a list of objects, each uri a string
    buffers = []
    for i, b in enumerate(doc.get("buffers") or []):
        uri = b.get("uri")
        if uri is None:
            buffers.append(blob)
        elif uri.startswith("data:"):
            import base64

            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            buffers.append((path.parent / unquote(uri)).read_bytes())
    return doc, buffers


def read_accessor(doc: dict, buffers: list[bytes], index: int) -> np.ndarray:
    """Accessor ``index`` as float64 (count, width); normalised integers mapped to [0, 1] / [-1, 1];
    sparse substitutions applied."""
    a = doc["accessors"][index]
    dtype = np.dtype(_COMPONENT[a["componentType"]])
    width = _WIDTH[a["type"]]
    count = a["count"]
    out = np.zeros((count, width), np.float64)
    if "bufferView" in a:
        view = doc["bufferViews"][a["bufferView"]]
        raw = buffers[view.get("buffer", 0)]
        start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        stride = view.get("byteStride") or dtype.itemsize * width
        rows = np.frombuffer(raw, np.uint8, count=stride * (count - 1) + dtype.itemsize * width, offset=start)
        rows = np.lib.stride_tricks.as_strided(rows, (count, dtype.itemsize * width), (stride, 1))
        out = np.ascontiguousarray(rows).view(dtype).reshape(count, width).astype(np.float64)
    sparse = a.get("sparse")
    if sparse:
        n = sparse["count"]
        iv = doc["bufferViews"][sparse["indices"]["bufferView"]]
        idx = np.frombuffer(buffers[iv.get("buffer", 0)], _COMPONENT[sparse["indices"]["componentType"]], count=n,
                            offset=iv.get("byteOffset", 0) + sparse["indices"].get("byteOffset", 0))
        vv = doc["bufferViews"][sparse["values"]["bufferView"]]
        vals = np.frombuffer(buffers[vv.get("buffer", 0)], dtype, count=n * width,
                             offset=vv.get("byteOffset", 0) + sparse["values"].get("byteOffset", 0))
        out[idx.astype(np.int64)] = vals.reshape(n, width)
    if a.get("normalized") and dtype.kind in "iu":
        info = np.iinfo(dtype)
        out = np.maximum(out / info.max, -1.0) if info.min < 0 else out / info.max
    return out


def _slerp(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Row-wise slerp of unit quaternions (n, 4) on the shorter arc, u (n,)."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    d = np.sum(a * b, axis=1)
    b = np.where(d[:, None] < 0, -b, b)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    small = d > 0.9995
    s = np.sin(theta)
    wa = np.where(small, 1 - u, np.sin((1 - u) * theta) / np.where(small, 1, s))
    wb = np.where(small, u, np.sin(u * theta) / np.where(small, 1, s))
    q = wa[:, None] * a + wb[:, None] * b
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def sample(times: np.ndarray, values: np.ndarray, interpolation: str, t: np.ndarray, rotation: bool) -> np.ndarray:
    """Values (len(t), width) of one sampler at times ``t`` (seconds).

    Args:
        times: (k,) key times, increasing.
        values: (k, width), or (3k, width) in-tangent/value/out-tangent triples for CUBICSPLINE.
        interpolation: ``LINEAR``, ``STEP`` or ``CUBICSPLINE``.
        t: (n,) sample times.
        rotation: quaternions (slerp for LINEAR; results normalised).
    """
    t = np.asarray(t, np.float64)
    cubic = interpolation == "CUBICSPLINE"
    triples = values.reshape(len(times), 3, -1) if cubic else None
    point = triples[:, 1] if cubic else values
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, max(len(times) - 2, 0))
    if len(times) == 1:
        out = np.repeat(point[:1], len(t), axis=0)
    else:
        td = times[k + 1] - times[k]
        u = np.clip((t - times[k]) / np.where(td > 0, td, 1.0), 0.0, 1.0)
        if interpolation == "STEP":
            out = np.where((t >= times[k + 1])[:, None], point[k + 1], point[k])
        elif cubic:
            h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
            h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
            out = (h00[:, None] * point[k] + (h10 * td)[:, None] * triples[k, 2] + h01[:, None] * point[k + 1]
                   + (h11 * td)[:, None] * triples[k + 1, 0])
        elif rotation:
            out = _slerp(point[k], point[k + 1], u)
        else:
            out = (1 - u)[:, None] * point[k] + u[:, None] * point[k + 1]
        out = np.where((t <= times[0])[:, None], point[0], out)
        out = np.where((t >= times[-1])[:, None], point[-1], out)
    if rotation:
        out = out / np.linalg.norm(out, axis=1, keepdims=True)
    return out


def frame_times(t0: float, t1: float, fps: float, max_frames: int | None = None) -> np.ndarray:
    """Sample times ``t0 + f / fps`` for f = 0 .. floor((t1 - t0) fps) (n, seconds).

    Raises:
        ClipTooLong: more than ``max_frames`` samples (default
            :data:`mimicbench.datagen.ingest.clip_length.MAX_CLIP_FRAMES`), or a non-finite key time;
            checked before any array is allocated.
    """
    from mimicbench.datagen.ingest.clip_length import check_clip_frames

    span = (t1 - t0) * fps + _FRAME_EPS
    what = f"glTF clip with keys from t = {t0:.6g} s to {t1:.6g} s at {fps:g} fps"
    n = check_clip_frames(math.floor(span) + 1 if math.isfinite(span) else span, what, max_frames)
    return t0 + np.arange(n) / fps


def resampled_document(doc: dict, buffers: list[bytes], fps: float,
                       max_frames: int | None = None) -> tuple[dict, bytes]:
    """A copy of ``doc`` whose animations are LINEAR keys at every frame, with one new buffer
    (the old buffers first, then the new keys). Returns (document, buffer bytes).

    Raises:
        ClipTooLong: a clip spans more than ``max_frames`` frames (:func:`frame_times`).
        ValueError: a key time or value of a clip is NaN or infinite.
    """
    doc = json.loads(json.dumps(doc))
    blob = bytearray()
    starts = []
    for b in buffers:
        blob.extend(b"\0" * (-len(blob) % 8))
        starts.append(len(blob))
        blob.extend(b)
    for view in doc.get("bufferViews", []):
        view["byteOffset"] = starts[view.get("buffer", 0)] + view.get("byteOffset", 0)
        view["buffer"] = 0

    def add(values: np.ndarray) -> int:
        values = np.ascontiguousarray(values, np.float32)
        blob.extend(b"\0" * (-len(blob) % 4))
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes})
        blob.extend(values.tobytes())
        acc = {"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126, "count": len(values),
               "type": _TYPES_BY_WIDTH[values.shape[1]]}
        if values.shape[1] == 1:
            acc["min"], acc["max"] = [float(values.min())], [float(values.max())]
        doc["accessors"].append(acc)
        return len(doc["accessors"]) - 1

    doc.setdefault("bufferViews", [])
    for anim in doc.get("animations", []):
        channels = [c for c in anim["channels"] if c["target"].get("path") in ("translation", "rotation", "scale")
                    and c["target"].get("node") is not None]
        samplers = anim["samplers"]
        inputs = {s["input"]: read_accessor(doc, buffers, s["input"])[:, 0] for s in samplers}
        used = [inputs[samplers[c["sampler"]]["input"]] for c in channels]
        _check_finite(anim, channels, samplers, inputs, doc, buffers)
        if not used:
            anim["channels"], anim["samplers"] = [], []
            continue
        times = frame_times(min(t.min() for t in used), max(t.max() for t in used), fps, max_frames)
        time_acc = add(times[:, None])
        new_samplers, new_channels = [], []
        for c in channels:
            s = samplers[c["sampler"]]
            values = read_accessor(doc, buffers, s["output"])
            out = sample(inputs[s["input"]], values, s.get("interpolation", "LINEAR"), times,
                         c["target"]["path"] == "rotation")
            new_samplers.append({"input": time_acc, "output": add(out), "interpolation": "LINEAR"})
            new_channels.append({"sampler": len(new_samplers) - 1, "target": dict(c["target"])})
        anim["samplers"], anim["channels"] = new_samplers, new_channels
    doc["animations"] = [a for a in doc.get("animations", []) if a["channels"]]
    if not doc["animations"]:
        doc.pop("animations")
    for key in ("materials", "textures", "images", "samplers"):
        doc.pop(key, None)
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            prim.pop("material", None)
    doc["buffers"] = [{"byteLength": len(blob)}]
    return doc, bytes(blob)


_TYPES_BY_WIDTH = {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


def _check_finite(anim: dict, channels: list, samplers: list, inputs: dict, doc: dict, buffers: list) -> None:
    """Raise ValueError naming the clip, node and path when a key time or value of one of
    ``channels`` is NaN or infinite (sampling would spread it over the clip, or Blender would
    silently replace it)."""
    for c in channels:
        s = samplers[c["sampler"]]
        for what, values in (("key times", inputs[s["input"]]), ("values", read_accessor(doc, buffers, s["output"]))):
            bad = int(values.size - np.count_nonzero(np.isfinite(values)))
            if bad:
                raise ValueError(f"glTF animation {anim.get('name', '?')!r}: {bad} NaN or infinite {what} in the "
                                 f"{c['target']['path']} of node {c['target']['node']}")


def write_glb(path: str | Path, doc: dict, blob: bytes) -> Path:
    """Write a GLB 2.0 file (JSON chunk padded with spaces, BIN chunk with zeros)."""
    doc = dict(doc, buffers=[{"byteLength": len(blob)}])
    text = json.dumps(doc).encode("utf-8")
    text += b" " * (-len(text) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    Path(path).write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    return Path(path)


def resample_gltf(src: str | Path, dst: str | Path, fps: float) -> dict:
    """Write ``dst`` (GLB): ``src`` with every clip resampled at ``fps``; returns its document."""
    doc, buffers = load_gltf(src)
    doc, blob = resampled_document(doc, buffers, fps)
    write_glb(dst, doc, blob)
    return doc
