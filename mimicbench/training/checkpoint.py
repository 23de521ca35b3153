"""Checkpoints: safetensors state dicts with a JSON header, and the loop's resume state.

A ``.safetensors`` file holds a module's ``state_dict`` (every tensor, contiguous, on CPU) and,
under the metadata key ``mimicbench``, a JSON header: ``model``, ``stage``, ``config`` (the whole
model config the module was built from), ``epoch`` (epochs trained), ``dataset`` (its folder
name, schema version and table fingerprints from manifest.json) and provenance (toolkit and torch
versions, UTC time; no git). Loading never unpickles anything.

Every file written here gets a digest file beside it, ``<name>.sha256`` (``sha256sum`` format:
``<hex>  <name>``). :func:`verify_digest` checks a file against it; training verifies the
checkpoint and the resume state before resuming, so a flipped byte is refused, never trained on.
Any checkpoint or resume state that cannot be read is a :class:`~mimicbench.runtime.errors.UserError`
naming the file (one line, no traceback).

The resume point of a stage is one unit (:func:`save_resume`): the weights (``last.safetensors``)
and the loop's state (``state.pt``) go into a new folder ``resume-<epoch>-<id>/``, and only then
does ``resume.json`` (written atomically) name that folder and both files' sha256. A kill or a full
disk at any moment leaves ``resume.json`` naming the previous, complete pair; older folders are
removed after the commit.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Callable

import torch

from mimicbench.runtime.errors import UserError

HEADER_KEY = "mimicbench"
DIGEST_SUFFIX = ".sha256"
RESUME_FILE = "resume.json"


class CheckpointMismatch(UserError, ValueError):
    """A readable checkpoint of another network than the one being loaded (the message names both)."""

WEIGHTS_FILE, STATE_FILE = "last.safetensors", "state.pt"


def dataset_provenance(dataset: str | os.PathLike) -> dict:
    """``{"name", "schema_version", "tables": {table: fingerprint}}`` of a dataset folder (what is known);
    for a folder without a manifest, ``"error"`` and ``"tables"``: ``{relative path: sha256}`` of its files."""
    from mimicbench.schemas.fingerprint import table_fingerprint
    from mimicbench.schemas.manifest import load_manifest, sha256_of

    info: dict = {"name": Path(dataset).name}
    try:
        manifest = load_manifest(dataset)
    except Exception as exc:  # a dataset without a manifest still trains if the stage can read it
        info["error"] = str(exc)
        root = Path(dataset)
        if root.is_dir():
            info["tables"] = {str(f.relative_to(root)): sha256_of(f) for f in sorted(root.rglob("*"))
                              if f.is_file() and not any(part.startswith(".") for part in f.relative_to(root).parts)}
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

    from mimicbench.schemas.manifest import atomic_write_bytes

    atomic_write_bytes(path, data)
    atomic_write_bytes(digest_path(path), f"{hashlib.sha256(data).hexdigest()}  {path.name}\n".encode())


def verify_digest(path: str | os.PathLike, again: str = "use --no-resume to start this stage over") -> None:
    """Check ``path`` against its digest file (:func:`digest_path`).

    Raises:
        UserError: the file or its digest file is missing or unreadable, or the digests differ
            (the message names the file and says how to start over).
    """
    from mimicbench.schemas.manifest import sha256_of

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


def state_dict_mismatch(module: torch.nn.Module, state: dict) -> str | None:
    """Why ``state`` (name -> tensor) does not fit ``module``'s parameters and buffers, in one line
    (missing, unexpected and other-shaped keys, counted, with the first of each), or None when it fits."""
    own = module.state_dict()
    missing = [k for k in own if k not in state]
    unexpected = [k for k in state if k not in own]
    shaped = [k for k in own if k in state and hasattr(state[k], "shape") and tuple(state[k].shape) != tuple(own[k].shape)]
    parts = [f"{len(keys)} {what} (e.g. {keys[0]!r}{extra(keys[0]) if extra else ''})"
             for keys, what, extra in ((missing, "missing", None), (unexpected, "unexpected", None),
                                       (shaped, "of another shape",
                                        lambda k: f": {tuple(state[k].shape)}, expected {tuple(own[k].shape)}"))
             if keys]
    return None if not parts else "; ".join(parts)


def load_module(path: str | os.PathLike, build: Callable[[dict], torch.nn.Module],
                device: str | torch.device = "cpu", expect: tuple[str, str] | None = None) -> torch.nn.Module:
    """Rebuild a module from a checkpoint.

    Args:
        path: a ``.safetensors`` file written by :func:`save_checkpoint`.
        build: ``config -> module``; called with the config stored in the header, so the module
            has the shapes it was trained with (e.g. ``lambda cfg: stage.build(cfg, context)``).
        device: where to put the module.
        expect: ``(model, stage)`` the checkpoint must be of (its header says), or None.

    Returns:
        The module with the stored weights (strict load), in eval() mode, on ``device``.

    Raises:
        UserError: one line naming the file and what it holds: a checkpoint of another model or
            stage than ``expect``, a config ``build`` cannot build, weights that do not fit.
    """
    state, header = load_checkpoint(path)
    what = f"a checkpoint of model {header.get('model')!r}, stage {header.get('stage')!r}"
    if expect is not None and (header.get("model"), header.get("stage")) != tuple(expect):
        raise CheckpointMismatch(f"{path}: {what}; expected one of model {expect[0]!r}, stage {expect[1]!r}")
    try:
        module = build(header.get("config"))
    except Exception as exc:
        first = (str(exc).strip().splitlines() or [""])[0][:200]
        raise CheckpointMismatch(f"{path}: {what} whose config does not build this network ({type(exc).__name__}: "
                        f"{first}); expected a checkpoint of the network being loaded") from None
    why = state_dict_mismatch(module, state)
    if why:
        raise CheckpointMismatch(f"{path}: {what} whose weights do not fit the network built from its config ({why}); "
                        f"expected a checkpoint of the network being loaded")
    module.load_state_dict(state, strict=True)
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


def _confined_name(stage_dir: Path, name, what: str) -> Path:
    """``stage_dir / name`` for a plain folder or file name read from ``resume.json`` (never a path elsewhere)."""
    if not isinstance(name, str) or not name or name in (".", "..") or "/" in name or "\\" in name \
            or Path(name).name != name:
        raise UserError(f"{stage_dir / RESUME_FILE}: {what} {name!r} is not a plain name inside {stage_dir}; "
                        f"use --no-resume to start this stage over")
    return stage_dir / name


def save_resume(stage_dir: str | os.PathLike, weights: dict[str, torch.Tensor], header: dict, state: dict) -> Path:
    """Write a stage's resume point as one unit: ``resume-<epoch>-<id>/last.safetensors`` (``weights``
    with ``header``) and ``state.pt`` (``state``, plus the weights' sha256), each with its digest file,
    then commit by writing ``resume.json`` atomically; then remove older resume folders (and the
    ``last.safetensors``/``state.pt`` pair an older layout kept beside them). Returns the new folder."""
    import hashlib
    import shutil
    import uuid

    from mimicbench.schemas.manifest import atomic_write_bytes

    stage_dir = Path(stage_dir)
    epoch = int(state["epoch"])
    folder = stage_dir / f"resume-{epoch:06d}-{uuid.uuid4().hex[:8]}"
    folder.mkdir(parents=True)
    weights_path = save_checkpoint(folder / WEIGHTS_FILE, weights, header)
    weights_sha = hashlib.sha256(weights_path.read_bytes()).hexdigest()
    state_path = save_state(folder / STATE_FILE, {**state, "weights_sha256": weights_sha})
    pointer = {"epoch": epoch, "folder": folder.name,
               "sha256": {WEIGHTS_FILE: weights_sha, STATE_FILE: hashlib.sha256(state_path.read_bytes()).hexdigest()}}
    atomic_write_bytes(stage_dir / RESUME_FILE, (json.dumps(pointer, indent=1, sort_keys=True) + "\n").encode())
    for old in stage_dir.glob("resume-*"):
        if old.is_dir() and old.name != folder.name:
            shutil.rmtree(old, ignore_errors=True)
    for name in (WEIGHTS_FILE, STATE_FILE):
        for legacy in (stage_dir / name, digest_path(stage_dir / name)):
            legacy.unlink(missing_ok=True)
    return folder


def find_resume(stage_dir: str | os.PathLike) -> tuple[Path, Path] | None:
    """``(weights, state)`` of the stage's committed resume point, both verified (sha256), or None
    when there is none. Reads ``resume.json`` (:func:`save_resume`); a stage folder of the older
    layout (``last.safetensors`` and ``state.pt`` beside each other) is read through their digest files.

    Raises:
        UserError: ``resume.json`` unreadable or naming a path outside the stage folder, or a file
            that is missing or does not match its recorded sha256 (one line, saying how to start over).
    """
    from mimicbench.schemas.manifest import sha256_of

    stage_dir = Path(stage_dir)
    pointer_path = stage_dir / RESUME_FILE
    again = "use --no-resume to start this stage over"
    if not pointer_path.is_file():
        weights, state = stage_dir / WEIGHTS_FILE, stage_dir / STATE_FILE
        if not (weights.is_file() and state.is_file()):
            return None
        verify_digest(state, again)
        verify_digest(weights, again)
        return weights, state
    try:
        pointer = json.loads(pointer_path.read_text())
        folder = _confined_name(stage_dir, pointer["folder"], "folder")
        digests = {name: str(pointer["sha256"][name]) for name in (WEIGHTS_FILE, STATE_FILE)}
    except UserError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserError(f"{pointer_path}: not a readable resume record ({type(exc).__name__}: {exc}); {again}") from None
    for name, want in digests.items():
        path = folder / name
        if not path.is_file():
            raise UserError(f"{path}: missing (named by {RESUME_FILE}); {again}")
        verify_digest(path, again)
        have = sha256_of(path)
        if have != want:
            raise UserError(f"{path}: sha256 {have[:12]}... does not match {RESUME_FILE} ({want[:12]}...): the file "
                            f"changed or is corrupt; {again}")
    return folder / WEIGHTS_FILE, folder / STATE_FILE
