"""The asset files a ``datagen ingest`` argument names: a file as given, a folder walked.

A folder stands for every asset file under it, at any depth, in sorted order: the suffixes whose
loader is ``walked`` (:data:`.loaders.LOADERS`: the Blender formats and MMD models, .pmx, .pmd). MMD motions (.vmd) in a folder are not taken
on their own: a model plays the .vmd files beside it whose names tie them to it
(:func:`mimicbench.datagen.mmd.ingest.motions_for`), so a folder of many models and motions does not play
every motion on every model. Hidden files and folders (names starting with ``.``) are skipped,
so a dataset's own ``.ingest`` cache or a ``.git`` folder under the walked folder is never read.
"""
from __future__ import annotations

import os
from pathlib import Path

from mimicbench.datagen.ingest.loaders import BLENDER_SUFFIXES, WALKED_SUFFIXES  # noqa: F401

FOLDER_SUFFIXES = WALKED_SUFFIXES  # the suffixes a folder walk takes (:data:`.loaders.LOADERS`)


def assets_in_folder(folder: Path, skip: Path | None = None) -> list[Path]:
    """Asset files under ``folder`` (any depth, sorted), resolved. Hidden folders and ``skip`` are
    pruned from the walk (never listed: a large ``.git`` costs nothing); hidden files are skipped."""
    found = []
    for root, dirs, files in os.walk(folder):
        here = Path(root)
        dirs[:] = [d for d in dirs if not d.startswith(".") and (skip is None or (here / d).resolve() != skip)]
        found += [(here / f).resolve() for f in files
                  if not f.startswith(".") and Path(f).suffix.lower() in FOLDER_SUFFIXES]
    return sorted(found)


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
