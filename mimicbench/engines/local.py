"""The local engine: items in this process (``jobs=1``) or in a process pool of ``jobs`` workers.

The pool keeps at most ``2 * jobs`` chunks in flight, so results (and the inputs shipped to the
workers) never pile up beyond a few chunks however many items there are. The per-item function
(often a ``partial`` holding a stage's tables, e.g. every character's embeddings) goes to each
worker once, when the worker starts, not with every chunk (as Ray's engine puts it in the object
store once).
"""
from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any, Callable, Iterator, Sequence

from mimicbench.engines.base import Engine, Outcome, TaskResources, call_chunk, call_item, chunks_of


_WORKER_FN = None  # in a pool worker: the per-item function it was started with


def _install(fn: Callable[[Any], Any]) -> None:
    global _WORKER_FN
    _WORKER_FN = fn


def _call_installed(items: Sequence[Any]) -> list[Outcome]:
    return call_chunk(_WORKER_FN, items)


class LocalEngine(Engine):
    """This machine's processes. ``jobs``: worker processes (1 runs every item in this process)."""

    name = "local"

    def __init__(self, jobs: int = 1):
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise ValueError(f"jobs: expected an integer >= 1, got {jobs!r}")
        self.jobs = jobs

    def describe(self) -> str:
        return f"local ({self.jobs} process{'es' if self.jobs > 1 else ''})"

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any], chunk: int = 1,
             resources: TaskResources = TaskResources()) -> Iterator[tuple[int, Outcome]]:
        if self.jobs == 1:
            for i, item in enumerate(items):
                yield i, call_item(fn, item)
            return
        pending = list(reversed(chunks_of(len(items), chunk)))
        with ProcessPoolExecutor(max_workers=self.jobs, initializer=_install, initargs=(fn,)) as pool:
            running: dict = {}
            while pending or running:
                while pending and len(running) < 2 * self.jobs:
                    rng = pending.pop()
                    running[pool.submit(_call_installed, [items[i] for i in rng])] = rng
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    rng = running.pop(fut)
                    for i, outcome in zip(rng, fut.result()):
                        yield i, outcome
