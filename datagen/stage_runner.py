"""Run a per-item stage function over many items, turning failures into status records.

A stage is a plain function ``item -> result``. :func:`run_stage` calls it for every item through
an engine (:mod:`mimicbench.engines`: this process, a process pool with ``jobs > 1``, or Ray tasks
on a local instance or a cluster), shows a progress bar, and returns the
results of the items that succeeded together with one :class:`~schemas.status.StatusRecord` per
item. An exception in one item fails that item only; the reason names the exception.
``on_done`` sees each result as soon as it is ready (in completion order), so a stage can write
finished work incrementally instead of holding everything until the end.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable, Sequence

from tqdm.auto import tqdm

from mimicbench.engines import Engine, LocalEngine, Outcome, TaskResources
from schemas.status import StatusRecord


def run_stage(
    items: Sequence[Any],
    fn: Callable[[Any], Any],
    stage: str,
    name_of: Callable[[Any], str] = str,
    jobs: int = 1,
    progress: bool = True,
    on_done: Callable[[int, bool, Any], None] | None = None,
    engine: Engine | None = None,
    chunk: int = 1,
    resources: TaskResources = TaskResources(),
    ordered: bool = False,
    keep_results: bool = True,
) -> tuple[list[Any], list[StatusRecord]]:
    """Apply ``fn`` to each item; return (results in item order, status records).

    Args:
        items: the inputs.
        fn: the per-item stage function (must be picklable for a process pool or Ray).
        stage: stage name written in the status records.
        name_of: the asset name of an item, for the status records.
        jobs: worker processes of the local engine when ``engine`` is None; 1 runs in this process.
        progress: show a progress bar.
        on_done: called in this process as ``on_done(index, ok, result)`` when an item finishes
            (``result`` None for a failed item); in completion order, or in item order with ``ordered``.
        engine: where the work runs (:mod:`mimicbench.engines`); default ``LocalEngine(jobs)``.
        chunk: items per task (per-task overhead is paid once a chunk).
        resources: what each task asks the engine for (CPUs, memory).
        ordered: call ``on_done`` in item order (a finished item waits for those before it), so a
            stage that writes as it goes writes the same bytes on every engine.
        keep_results: False returns no results (``on_done`` has seen them): memory stays bounded.
    """
    if jobs < 1:
        raise ValueError(f"jobs: expected >= 1, got {jobs}")
    engine = engine or LocalEngine(jobs)
    outcomes: list[tuple[bool, str, float] | None] = [None] * len(items)
    kept: dict[int, Any] = {}
    waiting: dict[int, Outcome] = {}
    next_in_order = 0
    bar = tqdm(total=len(items), desc=stage, unit="item", disable=not progress)

    def deliver(i: int, outcome: Outcome) -> None:
        if on_done is not None:
            on_done(i, outcome.ok, outcome.result)

    for i, outcome in engine.imap(fn, items, chunk, resources):
        outcomes[i] = (outcome.ok, outcome.reason, outcome.seconds)
        if outcome.ok and keep_results:
            kept[i] = outcome.result
        bar.update(1)
        if not ordered:
            deliver(i, outcome)
            continue
        waiting[i] = outcome
        while next_in_order in waiting:
            deliver(next_in_order, waiting.pop(next_in_order))
            next_in_order += 1
    bar.close()
    results, statuses = [], []
    for i, (item, (ok, reason, seconds)) in enumerate(zip(items, outcomes)):
        statuses.append(StatusRecord(name_of(item), stage, "ok" if ok else "failed", reason, seconds))
        if ok and keep_results:
            results.append(kept[i])
    return results, statuses


def summarize_statuses(statuses: Iterable[StatusRecord]) -> str:
    """One line per failure and a count line, for printing at the end of a stage."""
    statuses = list(statuses)
    failed = [s for s in statuses if s.status == "failed"]
    lines = [f"  FAILED {s.asset} [{s.stage}]: {s.reason}" for s in failed]
    lines.append(f"{len(statuses) - len(failed)} ok, {len(failed)} failed")
    return "\n".join(lines)
