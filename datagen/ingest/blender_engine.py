"""The local engine of ``datagen ingest``: ``jobs`` threads, each holding one Blender child
(:class:`~mimicbench.datagen.ingest.blender_pool.BlenderWorker`, started on its first asset) that
the Blender loader's task uses (:data:`.engine_task.BOUND`); the children stop when the run ends."""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor, as_completed
from queue import Queue
from typing import Any, Callable, Iterator, Sequence

from mimicbench.datagen.ingest import blender_pool
from mimicbench.datagen.ingest.engine_task import BOUND
from mimicbench.engines import Engine, Outcome, TaskResources, call_item


class BlenderThreads(Engine):
    """Items on ``jobs`` threads of this process, each with its own Blender child."""

    name = "local"

    def __init__(self, jobs: int = 1, assets_per_process: int = 50):
        self.jobs, self.assets_per_process = jobs, assets_per_process

    def describe(self) -> str:
        return f"local ({self.jobs} Blender process{'es' if self.jobs > 1 else ''})"

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any], chunk: int = 1,
             resources: TaskResources = TaskResources()) -> Iterator[tuple[int, Outcome]]:
        if not items:
            return
        workers: Queue = Queue()
        for _ in range(min(self.jobs, len(items))):
            workers.put(blender_pool.BlenderWorker(blender_pool.CHILD_MODULE, self.assets_per_process))

        def call(item) -> Outcome:
            worker = workers.get()
            BOUND.worker = worker
            try:
                return call_item(fn, item)
            finally:
                BOUND.worker = None
                workers.put(worker)

        try:
            with ThreadPoolExecutor(max_workers=self.jobs) as pool:
                futures = {pool.submit(call, item): i for i, item in enumerate(items)}
                for future in as_completed(futures):
                    yield futures[future], future.result()
        finally:
            while not workers.empty():
                workers.get().stop()
