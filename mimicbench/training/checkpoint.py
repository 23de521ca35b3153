"""Checkpoints: safetensors state dicts with a JSON header, and the loop's resume state.

A ``.safetensors`` file holds a module's ``state_dict`` (every tensor, contiguous, on CPU) and,
under the metadata key ``mimicbench``, a JSON header: ``model``, ``stage``, ``config`` (the whole
model config the module was built from), ``epoch`` (epochs trained), ``dataset`` (its folder
name, schema version and table fingerprints from manifest.json) and provenance (toolkit and torch
versions, UTC time; no git). Loading never unpickles anything.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Callable

import torch

HEADER_KEY = "mimicbench"


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


def _atomic_write(path: Path, data: bytes) -> None:
    from schemas.manifest import atomic_write_bytes

    atomic_write_bytes(path, data)


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


def read_header(path: str | os.PathLike) -> dict:
    """The JSON header of a checkpoint written by :func:`save_checkpoint`."""
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint (expected a .safetensors file written by "
                                f"`mimicbench train`)")
    with safe_open(str(path), framework="pt") as f:
        meta = f.metadata() or {}
    if HEADER_KEY not in meta:
        raise ValueError(f"{path}: a safetensors file without the {HEADER_KEY!r} header, so not a "
                         f"mimicbench checkpoint")
    return json.loads(meta[HEADER_KEY])


def load_checkpoint(path: str | os.PathLike, device: str | torch.device = "cpu") -> tuple[dict, dict]:
    """``(state_dict, header)`` of a checkpoint, tensors on ``device``."""
    from safetensors.torch import load_file

    header = read_header(path)
    return load_file(str(path), device=str(device)), header


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
    """Read what :func:`save_state` wrote (``weights_only=True``: no arbitrary unpickling)."""
    return torch.load(str(path), map_location="cpu", weights_only=True)
