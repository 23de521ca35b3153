"""The procedural character zoo: rigged, skinned, animated characters of every kind, offline.

``dataset.build_zoo(out_dir, num_characters, seed=0, ...)`` writes a dataset (characters and motions
shards, manifest, CARD.md); ``mimicbench zoo`` is its command line. Modules, one concept each:
``plan`` (counts, IDs, splits), ``templates/`` (one per category), ``skeleton``, ``naming``
(bone-name styles), ``mesh_builder``, ``skin_weights``, ``motions`` and ``clips``, ``build``
(one character), ``dataset`` (the whole zoo), ``export_obj``, ``export_bvh``, ``card``.
"""
from __future__ import annotations
