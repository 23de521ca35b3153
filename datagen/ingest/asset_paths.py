"""The asset files a ``datagen ingest`` argument names: a file as given, a folder walked.

A folder stands for every asset file under it, at any depth, in sorted order: the Blender
formats (``SUPPORTED``) and MMD models (.pmx, .pmd). MMD motions (.vmd) in a folder are not taken
on their own: a model plays the .vmd files beside it whose names tie them to it
(:func:`datagen.mmd.ingest.motions_for`), so a folder of many models and motions does not play
every motion on every model. Hidden files and folders (names starting with ``.``) are skipped,
so a dataset's own ``.ingest`` cache or a ``.git`` folder under the walked folder is never read.
"""
from __future__ import annotations

from pathlib import Path

from datagen.mmd import MODEL_SUFFIXES

BLENDER_SUFFIXES = (".glb", ".gltf", ".fbx", ".bvh", ".obj", ".blend")
FOLDER_SUFFIXES = BLENDER_SUFFIXES + MODEL_SUFFIXES


def assets_in_folder(folder: Path, skip: Path | None = None) -> list[Path]:
    """Asset files under ``folder`` (any depth, sorted, hidden names and anything under ``skip``
    skipped), resolved."""
    found = []
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).parts
        if any(part.startswith(".") for part in rel) or (skip is not None and p.resolve().is_relative_to(skip)):
            continue
        if p.is_file() and p.suffix.lower() in FOLDER_SUFFIXES:
            found.append(p.resolve())
    return found


def expand_asset_paths(paths, skip=None) -> tuple[list[Path], list[str]]:
    """(asset paths, empty folders): each path resolved, each folder replaced by
    :func:`assets_in_folder` (never walking into ``skip``, the dataset being written, whose
    exported .obj/.bvh files are not assets); duplicates dropped, first occurrence kept. A path
    that is neither a file nor a folder stays, so the caller reports it as not found."""
    skip = Path(skip).resolve() if skip is not None else None
    assets, seen, empty = [], set(), []
    for p in paths:
        a = Path(p).resolve()
        found = assets_in_folder(a, skip) if a.is_dir() else [a]
        if a.is_dir() and not found:
            empty.append(str(a))
        for f in found:
            if f not in seen:
                seen.add(f)
                assets.append(f)
    return assets, empty
