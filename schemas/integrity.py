"""What a reader checks before trusting a shard: its path stays in the dataset, its size and sha256.

Paths in ``manifest.json`` are relative to the dataset folder; :func:`entry_path` refuses an
absolute path, a ``..`` component, or one that leads outside the folder through a symlink, so a
manifest cannot make a reader (or ``resample``'s copy) touch files elsewhere.

:func:`verify_shard` compares a shard with its manifest entry: size (``bytes``) always, sha256
unless verification is off (``verify=False``, or the environment variable ``MIMICBENCH_VERIFY=0``,
which the CLI's ``--no-verify`` sets). A file is hashed once per process: the digest is cached by
path, size, inode, mtime and ctime (nanoseconds), so reading a shard again costs no second hash. A file whose status changed (ctime) less than
``RACY_SECONDS`` before it was hashed is not cached (the "racy timestamp" rule git uses): file
times tick coarsely, so a same-size rewrite within one tick would otherwise keep its old key.
"""
from __future__ import annotations

import os
import time
from pathlib import Path, PurePosixPath

from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.manifest import sha256_of

VERIFY_ENV = "MIMICBENCH_VERIFY"

_DIGESTS: dict[tuple, str] = {}
RACY_SECONDS = 2.0


def verify_enabled(verify: bool | None = None) -> bool:
    """``verify`` if given, else True unless ``MIMICBENCH_VERIFY`` is ``0``/``false``/``no``/``off``."""
    if verify is not None:
        return bool(verify)
    return os.environ.get(VERIFY_ENV, "1").strip().lower() not in ("0", "false", "no", "off")


def entry_path(root: str | os.PathLike, rel: str, where: str = "manifest.json") -> Path:
    """``root / rel`` for a path read from a manifest, refusing one that leaves ``root``.

    Raises:
        DatasetError: ``rel`` is not a string, is absolute, has a ``..`` or empty component, or
            resolves (following symlinks) outside ``root``.
    """
    root = Path(root)
    if not isinstance(rel, str) or not rel or "\x00" in rel:
        raise DatasetError(f"{root / where}: shard path {rel!r} is not a relative path string")
    parts = PurePosixPath(rel).parts
    if rel.startswith(("/", "\\")) or os.path.isabs(rel) or ":" in parts[0] or any(p in ("..", "") for p in parts) \
            or "\\" in rel:
        raise DatasetError(f"{root / where}: shard path {rel!r} leaves the dataset folder; expected a path "
                           f"inside it such as 'characters/train-00000-of-00001.parquet'")
    path = root.joinpath(*parts)
    real_root = root.resolve()
    if not path.resolve().is_relative_to(real_root):
        raise DatasetError(f"{root / where}: shard path {rel!r} leads outside the dataset folder "
                           f"(to {path.resolve()} through a symlink)")
    return path


def _key(path: Path, st: os.stat_result) -> tuple:
    return (str(path.resolve()), st.st_size, st.st_ino, st.st_mtime_ns, st.st_ctime_ns)


def _settled(st: os.stat_result) -> bool:
    """True when the file last changed long enough ago that a later change must show in its times."""
    return time.time_ns() - max(st.st_mtime_ns, st.st_ctime_ns) > RACY_SECONDS * 1e9


def cached_sha256(path: str | os.PathLike) -> str:
    """sha256 of ``path``, hashed once per process for an unchanged file."""
    path = Path(path)
    st = path.stat()
    key = _key(path, st)
    digest = _DIGESTS.get(key)
    if digest is None:
        digest = sha256_of(path)
        if _key(path, path.stat()) == key and _settled(st):  # unchanged while hashing, and not racy
            _DIGESTS[key] = digest
    return digest


def forget_digests() -> None:
    """Empty the digest cache (tests that edit a file in place within one clock tick)."""
    _DIGESTS.clear()


def verify_shard(path: Path, entry: dict, verify: bool | None = None) -> None:
    """Check ``path`` against its manifest ``entry``: present, size, and sha256 (unless turned off).

    Raises:
        DatasetError: naming the file: missing, another size, or another sha256.
    """
    try:
        st = path.stat()
    except FileNotFoundError:
        raise DatasetError(f"{path}: listed in manifest.json but missing") from None
    if not path.is_file():
        raise DatasetError(f"{path}: listed in manifest.json as a shard but not a regular file")
    size = entry.get("bytes")
    if size is not None and st.st_size != size:
        raise DatasetError(f"{path}: {st.st_size} bytes, manifest.json says {size}: the file changed or is "
                           f"truncated (run `mimicbench validate`; rebuild it with the stage that made it)")
    if verify_enabled(verify):
        digest = cached_sha256(path)
        if digest != entry.get("sha256"):
            raise DatasetError(f"{path}: sha256 {digest[:12]}... differs from manifest.json's "
                               f"{str(entry.get('sha256'))[:12]}...: the file changed or is damaged (rebuild it "
                               f"with the stage that made it; --no-verify or MIMICBENCH_VERIFY=0 skips this check)")
