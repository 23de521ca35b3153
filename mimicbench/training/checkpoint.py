"""Checkpoints: safetensors state dicts with a JSON header, and the loop's resume state.

A ``.safetensors`` file holds a module's ``state_dict`` (every tensor, contiguous, on CPU) and,
under the metadata key ``mimicbench``, a JSON header: ``model``, ``stage``, ``config`` (the whole
model config the module was built from), ``epoch`` (epochs trained), ``dataset`` (its folder
name, schema version and table fingerprints from manifest.json) and provenance (toolkit and torch
versions, UTC time; no git). Loading never unpickles anything.

Every file written here gets a digest file beside it, ``<name>.sha256`` (``sha256sum`` format:
``<hex>  <name>``). :func:`verify_digest` checks a file against it; training verifies the
checkpoint and the resume state before resuming, so a flipped byte is refused, never trained on.
Any checkpoint or resume state that cannot be read is a :class:`~mimicbench.errors.UserError`
naming the file (one line, no traceback).
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Callable

import torch

from mimicbench.errors import UserError

HEADER_KEY = "mimicbench"
DIGEST_SUFFIX = ".sha256"


def dataset_provenance(dataset: str | os.PathLike) -> dict:
    """``{"name", "schema_version", "tables": {table: fingerprint}}`` of a dataset folder (what is known)."""
    from schemas.fingerprint import table_fingerprint
    from schemas.manifest import load_manifest

    info: dict = {"name": Path(dataset).name}
    try:
        manifest = load_manifest(dataset)
    except Exception as exc:  # a dataset without a manifest still trains if the stage can read it
        info["error"] = str(exc)
        return info
    info["schema_version"] = manifest.get("schema_version")
    info["tables"] = {t: table_fingerprint(dataset, t, manifest) for t in sorted(manifest.get("tables", {}))
                      if manifest["tables"][t].get("shards")}
    return info


def provenance() -> dict:
    """Toolkit and torch versions and the UTC time, for a checkpoint header."""
    from mimicbench import __version__

    return {"mimicbench": __version__, "torch": torch.__version__,
            "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def digest_path(path: str | os.PathLike) -> Path:
    """The digest file beside ``path``: ``<name>.sha256``."""
    path = Path(path)
    return path.with_name(path.name + DIGEST_SUFFIX)


def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` and its sha256 to :func:`digest_path` (each atomically)."""
    import hashlib

    from schemas.manifest import atomic_write_bytes

    atomic_write_bytes(path, data)
    atomic_write_bytes(digest_path(path), f"{hashlib.sha256(data).hexdigest()}  {path.name}\n".encode())


def verify_digest(path: str | os.PathLike, again: str = "use --no-resume to start this stage over") -> None:
    """Check ``path`` against its digest file (:func:`digest_path`).

    Raises:
        UserError: the file or its digest file is missing or unreadable, or the digests differ
            (the message names the file and says how to start over).
    """
    from schemas.manifest import sha256_of

    path = Path(path)
    dpath = digest_path(path)
    try:
        text = dpath.read_text(encoding="ascii")
    except FileNotFoundError:
        raise UserError(f"{path}: no {dpath.name} beside it, so it cannot be verified; {again}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{dpath}: unreadable digest file ({exc}); {again}") from None
    want = text.split()[0].lower() if text.split() else ""
    if len(want) != 64 or any(c not in "0123456789abcdef" for c in want):
        raise UserError(f"{dpath}: expected '<64 hex>  {path.name}', got {text[:80]!r}; {again}")
    if not path.is_file():
        raise UserError(f"{path}: missing (its digest file {dpath.name} is there); {again}")
    have = sha256_of(path)
    if have != want:
        raise UserError(f"{path}: sha256 {have[:12]}... does not match {dpath.name} ({want[:12]}...): the file "
                        f"changed or is corrupt; {again}")


def _unreadable(path, what: str, exc: BaseException) -> UserError:
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
    return UserError(f"{path}: not a readable {what} ({type(exc).__name__}: {first})")


def save_checkpoint(path: str | os.PathLike, state_dict: dict[str, torch.Tensor], header: dict) -> Path:
    """Write ``state_dict`` and ``header`` to ``path`` (.safetensors) atomically.

    Tensors that share storage (tied weights) are stored as separate copies.
    """
    from safetensors.torch import save

    tensors = {k: v.detach().to("cpu").contiguous().clone() for k, v in state_dict.items()}
    data = save(tensors, metadata={HEADER_KEY: json.dumps(header, sort_keys=True)})
    path = Path(path)
    _atomic_write(path, data)
    return path


def stage_weights(folder: str | os.PathLike, stage: str, model: str) -> Path:
    """The weights of ``stage`` in a checkpoint folder: ``FOLDER/<stage>.safetensors`` (the shipped
    layout) or ``FOLDER/<stage>/model.safetensors`` (a run of ``mimicbench train <model>``)."""
    folder = Path(folder)
    for p in (folder / f"{stage}.safetensors", folder / stage / "model.safetensors"):
        if p.is_file():
            return p
    raise FileNotFoundError(f"{folder}: no weights for stage {stage!r} (expected {stage}.safetensors or "
                            f"{stage}/model.safetensors; train with `mimicbench train {model} DATASET --out RUN`)")


def read_header(path: str | os.PathLike) -> dict:
    """The JSON header of a checkpoint written by :func:`save_checkpoint`."""
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint (expected a .safetensors file written by "
                                f"`mimicbench train`)")
    try:
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
    except Exception as exc:  # safetensors' own error types: a truncated or garbled header
        raise _unreadable(path, "safetensors checkpoint", exc) from None
    if HEADER_KEY not in meta:
        raise ValueError(f"{path}: a safetensors file without the {HEADER_KEY!r} header, so not a "
                         f"mimicbench checkpoint")
    try:
        return json.loads(meta[HEADER_KEY])
    except ValueError as exc:
        raise _unreadable(path, "checkpoint header", exc) from None


def load_checkpoint(path: str | os.PathLike, device: str | torch.device = "cpu") -> tuple[dict, dict]:
    """``(state_dict, header)`` of a checkpoint, tensors on ``device``."""
    from safetensors.torch import load_file

    header = read_header(path)
    try:
        return load_file(str(path), device=str(device)), header
    except Exception as exc:
        raise _unreadable(path, "safetensors checkpoint", exc) from None


def load_module(path: str | os.PathLike, build: Callable[[dict], torch.nn.Module],
                device: str | torch.device = "cpu") -> torch.nn.Module:
    """Rebuild a module from a checkpoint.

    Args:
        path: a ``.safetensors`` file written by :func:`save_checkpoint`.
        build: ``config -> module``; called with the config stored in the header, so the module
            has the shapes it was trained with (e.g. ``lambda cfg: stage.build(cfg, context)``).
        device: where to put the module.

    Returns:
        The module with the stored weights (strict load), in eval() mode, on ``device``.
    """
    state, header = load_checkpoint(path)
    module = build(header["config"])
    try:
        module.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        raise ValueError(f"{path}: weights do not fit the module built from its own config "
                         f"(model {header.get('model')!r}, stage {header.get('stage')!r}): {exc}") from exc
    return module.to(device).eval()


def save_state(path: str | os.PathLike, state: dict) -> Path:
    """Write the loop's resume state (optimizer state dict, epoch, RNG states) with torch.save, atomically.

    ``state`` must hold only tensors, numbers, strings, lists, tuples and dicts, so that
    :func:`load_state` can read it with ``weights_only=True``.
    """
    import io

    buf = io.BytesIO()
    torch.save(state, buf)
    path = Path(path)
    _atomic_write(path, buf.getvalue())
    return path


def load_state(path: str | os.PathLike) -> dict:
    """Read what :func:`save_state` wrote (``weights_only=True``: no arbitrary unpickling).

    Raises:
        UserError: the file is not a readable resume state (a damaged pickle or zip part, or a
            pickle that ``weights_only`` refuses), one line naming the file.
    """
    try:
        return torch.load(str(path), map_location="cpu", weights_only=True)
    except Exception as exc:  # UnpicklingError, RuntimeError from the zip reader, EOFError, ...
        raise _unreadable(path, "resume state", exc) from None
