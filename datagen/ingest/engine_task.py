"""One asset's Blender ingest as an engine task (``datagen ingest --engine ray``).

Each Ray worker process keeps its own Blender child (:class:`~mimicbench.datagen.ingest.blender_pool.BlenderWorker`,
a fresh one after ``assets_per_process`` assets or a crash), so a task costs one import, not a
Blender start-up. The task writes the asset's cache files (``OUT/.ingest_cache/<key>.npz``/``.json``,
on a file system every node sees) and returns its status row; the driver builds the shards from
the cache in the same order as the local engine, so the output bytes are the same.
"""
from __future__ import annotations

import threading
from pathlib import Path

from mimicbench.datagen.ingest.loader import Loader
from mimicbench.engines import TaskResources

TASK_RESOURCES = TaskResources(num_cpus=1, memory=3 << 30)  # a Blender process holding one asset
_WORKERS: dict = {}  # per engine worker process: assets_per_process -> BlenderWorker
BOUND = threading.local()  # ``worker``: the BlenderWorker a thread of :class:`.blender_engine.BlenderThreads` holds

BLENDER = Loader("blender", "mimicbench.datagen.ingest.engine_task:ingest_task", in_blender=True)
BLENDER_LOADERS = {s: BLENDER for s in (".glb", ".gltf", ".fbx", ".bvh", ".obj", ".blend")}
"""The formats Blender imports (:mod:`.blender_child`), for :data:`.loaders.LOADERS`."""


def ingest_task(item: tuple) -> object:
    """``(asset, out_npz, child_options, timeout, assets_per_process)`` -> the asset's StatusRecord,
    from the Blender child bound to this thread (:data:`BOUND`), else this process's own."""
    from mimicbench.datagen.ingest import blender_pool
    from mimicbench.datagen.ingest.job import run_job

    asset, out_npz, options, timeout, per_process = item
    worker = getattr(BOUND, "worker", None) or _WORKERS.get(per_process)
    if worker is None:
        worker = _WORKERS[per_process] = blender_pool.BlenderWorker(blender_pool.CHILD_MODULE, per_process)
    return run_job(worker, Path(asset), Path(out_npz), options, timeout)
