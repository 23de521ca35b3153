"""A glTF file's JSON document and binary chunk, read once for the URI check and the loader; and
its external resources: a buffer or image ``uri`` that points outside the asset's folder
(``../x.bin``, ``/etc/passwd``, ``file:///...``) is refused unless the user allows it, so an
untrusted asset cannot make ingest read arbitrary files.

GLB (glTF 2.0 section 4.4): a 12-byte header (``glTF``, version, total length), then chunks of
(length, type, data) up to that length; the first chunk is the JSON, optionally followed by one
BIN chunk; other chunk types are ignored. A file with a second JSON chunk, a JSON chunk that is not first, a
second BIN chunk or a chunk running past the end is refused here, so the URI check and the loader
can never read different documents.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path
from urllib.parse import unquote, urlparse

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942


def parse_glb(data: bytes, where: str = "GLB") -> tuple[bytes, bytes | None]:
    """(JSON chunk bytes, BIN chunk bytes or None) of a GLB file's ``data``.

    Raises:
        ValueError: truncated header or chunk, no JSON chunk first, or a repeated JSON/BIN chunk.
    """
    if len(data) < 20:
        raise ValueError(f"{where}: truncated GLB header ({len(data)} bytes, expected at least 20)")
    total = struct.unpack_from("<I", data, 8)[0]
    if total > len(data):
        raise ValueError(f"{where}: truncated GLB: the header says {total} bytes, the file has {len(data)}")
    data = data[:total]  # bytes after the declared length are not part of the GLB
    offset, doc, blob, index = 12, None, None, 0
    while offset < len(data):
        if offset + 8 > len(data):
            raise ValueError(f"{where}: truncated GLB chunk header at byte {offset}")
        size, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + size > len(data):
            raise ValueError(f"{where}: GLB chunk {index} at byte {offset} runs past the end of the file "
                             f"({size} bytes declared, {len(data) - offset - 8} left)")
        chunk = data[offset + 8: offset + 8 + size]
        if index == 0 and kind != CHUNK_JSON:
            raise ValueError(f"{where}: the first GLB chunk is not JSON (type 0x{kind:08X}); glTF 2.0 requires "
                             f"the JSON chunk first")
        if kind == CHUNK_JSON and index > 0:
            raise ValueError(f"{where}: GLB chunk {index} at byte {offset} is a second JSON chunk; a GLB holds "
                             f"exactly one, first")
        if kind == CHUNK_BIN:
            if blob is not None:
                raise ValueError(f"{where}: GLB chunk {index} at byte {offset} is a second BIN chunk; a GLB holds "
                                 f"at most one")
            blob = bytes(chunk)
        elif kind == CHUNK_JSON:
            doc = bytes(chunk)
        offset += 8 + size
        index += 1
    return doc, blob


def gltf_document(path: str | Path) -> tuple[dict, bytes | None]:
    """(JSON document, GLB BIN chunk or None) of a ``.gltf`` or ``.glb`` file.

    Raises:
        ValueError: a malformed GLB (:func:`parse_glb`), JSON that does not parse, or a document
            that is not a JSON object.
    """
    data = Path(path).read_bytes()
    blob = None
    if data[:4] == GLB_MAGIC:
        text, blob = parse_glb(data, str(path))
    else:
        text = data
    try:
        doc = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"{path}: the glTF JSON does not parse ({exc})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: the glTF JSON is a {type(doc).__name__}, expected an object")
    return doc, blob


def gltf_json(path: str | Path) -> dict:
    """The JSON document of a ``.gltf`` file or of a ``.glb`` file's (single) JSON chunk."""
    return gltf_document(path)[0]


def resource_uris(doc: dict, where: str = "glTF") -> list[tuple[str, int, str | None]]:
    """(``buffers`` or ``images``, index, uri or None) of every buffer and image of ``doc``.

    Raises:
        ValueError: ``buffers``/``images`` not a list of objects, or a ``uri`` that is not a string.
    """
    out = []
    for kind in ("buffers", "images"):
        items = doc.get(kind, [])
        if not isinstance(items, list):
            raise ValueError(f"{where}: {kind} is a {type(items).__name__}, expected a list of objects")
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise ValueError(f"{where}: {kind}[{i}] is a {type(item).__name__}, expected an object")
            uri = item.get("uri")
            if uri is not None and not isinstance(uri, str):
                raise ValueError(f"{where}: {kind}[{i}] uri is a {type(uri).__name__}, expected a string")
            out.append((kind, i, uri))
    return out


def external_uri_problems(path: str | Path) -> list[str]:
    """The buffer and image URIs of a glTF file that resolve outside its folder (empty when none).

    ``data:`` URIs are embedded and fine; a relative path must stay under the file's folder. The
    document is read by :func:`gltf_document`, as the loader reads it.

    Raises:
        ValueError: the file is not a readable glTF document (the message says why).
    """
    path = Path(path).resolve()
    doc, _ = gltf_document(path)
    folder = path.parent
    problems = []
    for kind, i, uri in resource_uris(doc, str(path)):
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
