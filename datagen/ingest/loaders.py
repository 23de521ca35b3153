"""Ingest's formats in one table, file suffix -> :class:`Loader`, as trimesh's ``exchange/load.py``
merges its format modules' loaders: each format module exports its own (the Blender formats in
:mod:`.engine_task`, MMD in :mod:`mimicbench.datagen.mmd.ingest`) and :data:`LOADERS` merges them.
A folder is walked for the suffixes whose loader is ``walked``; a loader with no ``task`` (a .vmd
motion) is read by the model it plays on, not on its own.
"""
from __future__ import annotations

from pathlib import Path

from mimicbench.datagen.ingest.loader import Loader


def _merged() -> dict[str, Loader]:
    from mimicbench.datagen.ingest.engine_task import BLENDER_LOADERS
    from mimicbench.datagen.mmd.loaders import MMD_LOADERS

    table: dict[str, Loader] = {}
    for loaders in (BLENDER_LOADERS, MMD_LOADERS):
        for suffix, loader in loaders.items():
            if suffix in table:
                raise RuntimeError(f"two ingest loaders for {suffix}: {table[suffix].name} and {loader.name}")
            table[suffix] = loader
    return table


LOADERS: dict[str, Loader] = _merged()
"""File suffix (lower case, with the dot) -> its loader."""
BY_NAME: dict[str, Loader] = {loader.name: loader for loader in LOADERS.values()}
WALKED_SUFFIXES = tuple(s for s, loader in LOADERS.items() if loader.walked)
BLENDER_SUFFIXES = tuple(s for s, loader in LOADERS.items() if loader.in_blender)


def loader_for(path) -> Loader | None:
    """The loader of ``path``'s suffix (None: not an asset ingest reads)."""
    return LOADERS.get(Path(path).suffix.lower())


def ingest_item(item: tuple):
    """The engine's per-item function: ``(loader name, payload)`` -> that loader's task of the payload."""
    name, payload = item
    return BY_NAME[name].function()(payload)
