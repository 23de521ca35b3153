"""External resources of a glTF file: a buffer or image ``uri`` that points outside the asset's
folder (``../x.bin``, ``/etc/passwd``, ``file:///...``) is refused unless the user allows it,
so an untrusted asset cannot make ingest read arbitrary files."""
from __future__ import annotations

import json
import struct
from pathlib import Path
from urllib.parse import unquote, urlparse


def gltf_json(path: str | Path) -> dict:
    """The JSON document of a ``.gltf`` file or of a ``.glb`` file's first chunk."""
    data = Path(path).read_bytes()
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise ValueError(f"{path}: truncated GLB header")
        size, kind = struct.unpack_from("<II", data, 12)
        if kind != 0x4E4F534A:
            raise ValueError(f"{path}: the first GLB chunk is not JSON")
        return json.loads(data[20: 20 + size].decode("utf-8"))
    return json.loads(data.decode("utf-8"))


def external_uri_problems(path: str | Path) -> list[str]:
    """The buffer and image URIs of a glTF file that resolve outside its folder (empty when none).

    ``data:`` URIs are embedded and fine; a relative path must stay under the file's folder.
    A file whose JSON cannot be read yields no problem here (Blender then reports it).
    """
    path = Path(path).resolve()
    try:
        doc = gltf_json(path)
    except (ValueError, UnicodeDecodeError, OSError):
        return []
    folder = path.parent
    problems = []
    for kind in ("buffers", "images"):
        for i, item in enumerate(doc.get(kind) or []):
            uri = item.get("uri") if isinstance(item, dict) else None
            if not uri or uri.startswith("data:"):
                continue
            parsed = urlparse(uri)
            if parsed.scheme and len(parsed.scheme) > 1:  # file:, http:, ... (a 1-letter scheme is a drive)
                problems.append(f"{kind}[{i}] uri {uri!r} is not a relative path")
                continue
            target = Path(unquote(uri))
            resolved = (folder / target).resolve()
            if target.is_absolute() or not resolved.is_relative_to(folder):
                problems.append(f"{kind}[{i}] uri {uri!r} resolves outside {folder}")
    return problems
