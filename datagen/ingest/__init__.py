"""Ingest real rigged assets through Blender (bpy).

- :mod:`.runner` plans the work (IDs, cache keys, splits), runs the Blender jobs and writes the
  tables, CARD.md and status rows; :mod:`.blender_pool` keeps Blender child processes that each
  ingest many assets; :mod:`.blender_child` is what runs inside Blender.
- :mod:`.gltf_resample` evaluates glTF clips by the specification before Blender imports them;
  :mod:`.gltf_defaults` gives the file's default pose; :mod:`.uris` refuses resources outside the
  asset's folder.
- :mod:`.identity` (character IDs, cache keys, skeleton IDs), :mod:`.category` (categories from
  bone names and the skeleton), :mod:`.card` (CARD.md), :mod:`.export` (.obj and .bvh files).
"""
from __future__ import annotations
