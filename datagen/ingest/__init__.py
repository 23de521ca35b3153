"""Ingest real rigged assets through Blender (bpy): :mod:`.blender_child` runs in a child
process per asset; :mod:`.runner` collects results into dataset records; :mod:`.export` writes
.obj and .bvh files."""
from datagen.ingest.runner import ingest_assets

__all__ = ["ingest_assets"]
