"""What every engine shares: one item's outcome, the resources a task declares, chunking.

An engine runs a stage's per-item function ``fn(item) -> result`` over many items and yields
``(index, Outcome)`` pairs as items finish (in completion order); :func:`mimicbench.datagen.stage_runner.run_stage`
turns them into results in item order and status records. Items travel in chunks (a list of
consecutive items a task), so per-task overhead is paid once per chunk.
"""
from __future__ import annotations

import time
import traceback
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence


@dataclass(frozen=True)
class Outcome:
    """One item's result: ``ok``, the ``result`` (None when failed), the failure ``reason``, ``seconds``."""

    ok: bool
    result: Any
    reason: str
    seconds: float


@dataclass(frozen=True)
class TaskResources:
    """What one task (one chunk) asks the scheduler for.

    Attributes:
        num_cpus: CPU cores a task uses (Blender and mesh work: 1).
        memory: bytes of memory a task needs (Ray's ``memory`` resource), or None for no claim.
    """

    num_cpus: float = 1.0
    memory: int | None = None

    def __post_init__(self):
        if not self.num_cpus > 0:
            raise ValueError(f"num_cpus: expected > 0, got {self.num_cpus}")
        if self.memory is not None and self.memory <= 0:
            raise ValueError(f"memory: expected bytes > 0 or None, got {self.memory}")


def call_item(fn: Callable[[Any], Any], item: Any) -> Outcome:
    """Run ``fn(item)``; an exception becomes a failed Outcome naming it and where it was raised."""
    start = time.perf_counter()
    try:
        return Outcome(True, fn(item), "", time.perf_counter() - start)
    except Exception as exc:  # one bad item must not end the run
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {tb[-1].filename.split('/')[-1]}:{tb[-1].lineno})" if tb else ""
        return Outcome(False, None, f"{type(exc).__name__}: {exc}{where}", time.perf_counter() - start)


def call_chunk(fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Outcome]:
    """:func:`call_item` over a chunk of items, in order."""
    return [call_item(fn, item) for item in items]


def chunks_of(n: int, chunk: int) -> list[range]:
    """Index ranges of consecutive chunks of at most ``chunk`` items covering ``range(n)``."""
    if chunk < 1:
        raise ValueError(f"chunk: expected >= 1 items a task, got {chunk}")
    return [range(i, min(i + chunk, n)) for i in range(0, n, chunk)]


class Engine:
    """Runs a per-item function over items; subclasses implement :meth:`imap`."""

    name = "engine"

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any], chunk: int = 1,
             resources: TaskResources = TaskResources()) -> Iterator[tuple[int, Outcome]]:
        """Yield ``(index, Outcome)`` for every item, in completion order."""
        raise NotImplementedError

    def describe(self) -> str:
        return self.name
