"""manifest.json: schema version, shards with row counts, sizes and sha256, configs, completeness.

Readers use :func:`load_manifest`, which refuses a folder with no manifest, an unparseable one or
one of an unknown schema major version (a missing manifest is never read as an empty dataset).
Writers that may start a new dataset use :func:`load_manifest_for_write`, which returns an empty
manifest for a new folder but refuses to take over a manifest it cannot read or of another major
version. A stage that writes over several steps marks the dataset incomplete first
(:func:`mark_incomplete`) and complete at the end (:func:`mark_complete`): a killed run leaves
``"complete": false`` behind, which ``validate`` and the readers report.

Files are written under a temporary name, fsynced and renamed into place, with the permissions a
plain ``open()`` would give under the user's umask (``mkstemp`` alone would leave them 0600).
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.version import SCHEMA_VERSION, is_compatible, newer

MANIFEST = "manifest.json"


def sha256_of(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def empty_manifest() -> dict:
    return {"format": "mimicbench-dataset", "schema_version": SCHEMA_VERSION, "complete": True,
            "tables": {}, "configs": {}}


def _parse(path: Path) -> dict:
    try:
        manifest = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: not valid JSON ({exc})") from exc
    if not isinstance(manifest, dict):
        raise DatasetError(f"{path}: expected a JSON object, got {type(manifest).__name__}")
    version = manifest.get("schema_version")
    if not isinstance(version, str) or not is_compatible(version):
        raise DatasetError(f"{path}: unknown schema version {version!r}, expected {SCHEMA_VERSION!r} (this "
                           f"mimicbench reads {SCHEMA_VERSION.split('.')[0]}.x; use a matching mimicbench version)")
    manifest.setdefault("tables", {})
    manifest.setdefault("configs", {})
    _check_structure(path, manifest)
    return manifest


SHARD_FIELDS = {"path": str, "split": str, "rows": int, "sha256": str}


def _check_structure(path: Path, manifest: dict) -> None:
    """Raise DatasetError naming ``path`` when the manifest's fields are not of the documented types."""
    def bad(what: str):
        raise DatasetError(f"{path}: {what}; see schemas/FORMAT.md for the manifest's layout")

    if not isinstance(manifest["tables"], dict):
        bad("'tables' must be an object")
    if not isinstance(manifest["configs"], dict) or not all(isinstance(c, dict) for c in manifest["configs"].values()):
        bad("'configs' must be an object of objects")
    if not isinstance(manifest.get("complete", True), bool):
        bad("'complete' must be true or false")
    if not isinstance(manifest.get("pending", {}), dict):
        bad("'pending' must be an object")
    for table, info in manifest["tables"].items():
        if not isinstance(info, dict) or not isinstance(info.get("shards", []), list):
            bad(f"table {table!r} must be an object with a 'shards' list")
        for i, entry in enumerate(info.get("shards", [])):
            if not isinstance(entry, dict):
                bad(f"table {table!r} shard {i} must be an object")
            for key, kind in SHARD_FIELDS.items():
                value = entry.get(key)
                if not isinstance(value, kind) or isinstance(value, bool) or (kind is int and value < 0):
                    bad(f"table {table!r} shard {i}: {key!r} must be "
                        f"{'a non-negative integer' if kind is int else 'a string'}, got {value!r}")
            size = entry.get("bytes")
            if size is not None and (not isinstance(size, int) or isinstance(size, bool) or size < 0):
                bad(f"table {table!r} shard {i}: 'bytes' must be a non-negative integer, got {size!r}")


def load_manifest(root: str | os.PathLike) -> dict:
    """Read ``root/manifest.json`` for reading the dataset.

    Raises:
        DatasetError: ``root`` is not a folder, has no manifest.json (not a dataset), or the
            manifest is not valid JSON or of an unknown schema major version.
    """
    root = Path(root)
    path = root / MANIFEST
    if not root.is_dir():
        raise DatasetError(f"{root}: no such dataset folder")
    if not path.is_file():
        raise DatasetError(f"{path}: missing, so {root} is not a dataset (expected the output of zoo, "
                           f"datagen ingest or datagen resample)")
    return _parse(path)


def load_manifest_for_write(root: str | os.PathLike) -> dict:
    """The manifest to update when writing into ``root``: an empty one for a new dataset.

    Raises:
        DatasetError: an existing manifest is unreadable or of another schema major version (it
            is never silently replaced).
    """
    path = Path(root) / MANIFEST
    if not path.exists():
        return empty_manifest()
    manifest = _parse(path)
    manifest["schema_version"] = newer(manifest["schema_version"], SCHEMA_VERSION)
    return manifest


def is_complete(manifest: dict) -> bool:
    """False while a stage that writes in steps has not finished (manifests without the key: True)."""
    return manifest.get("complete", True) is not False


def incomplete_reason(root, manifest: dict) -> str:
    stage = (manifest.get("pending") or {}).get("stage", "a stage")
    return (f"{Path(root) / MANIFEST}: the dataset is incomplete ({stage} started writing it and did not "
            f"finish); re-run {stage} to resume")


def mark_incomplete(root: str | os.PathLike, stage: str, config: dict | None = None) -> dict:
    """Record that ``stage`` is writing ``root`` (``complete: false``); returns the saved manifest."""
    manifest = load_manifest_for_write(root)
    manifest["complete"] = False
    manifest["pending"] = {"stage": stage, **({"config": config} if config is not None else {})}
    save_manifest(root, manifest)
    return manifest


def mark_complete(root: str | os.PathLike) -> None:
    """Record that the stage writing ``root`` finished (``complete: true``)."""
    manifest = load_manifest_for_write(root)
    manifest["complete"] = True
    manifest.pop("pending", None)
    save_manifest(root, manifest)


def current_umask() -> int:
    """The process umask (read without changing it where /proc allows)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def chmod_like_open(path: str | os.PathLike) -> None:
    """Give a file made by ``mkstemp`` (mode 0600) the mode ``open()`` would: 0666 minus the umask."""
    os.chmod(path, 0o666 & ~current_umask())


def fsync_file(path: str | os.PathLike) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path`` (fsynced, umask mode), then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        chmod_like_open(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):  # a full disk's write error names no file: name the one being written
            from mimicbench.schemas.errors import os_error_at

            raise os_error_at(exc, path) from exc
        raise


def save_manifest(root: str | os.PathLike, manifest: dict) -> None:
    """Write the manifest atomically."""
    atomic_write_bytes(Path(root) / MANIFEST, (json.dumps(manifest, indent=2, sort_keys=True) + "\n").encode())
