"""Ingest real rigged assets through Blender (bpy): :mod:`.blender_child` runs in a child
process per asset; :mod:`.runner` collects results into dataset records; :mod:`.export` writes
.obj and .bvh files."""
from __future__ import annotations

import importlib

_LAZY = {
    "ingest_assets": "datagen.ingest.runner",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """Import the public functions on first use, so the CLI starts fast."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
