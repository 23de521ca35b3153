"""Run a per-item stage function over many items, turning failures into status records.

A stage is a plain function ``item -> result``. :func:`run_stage` calls it for every item (in
this process, or in a process pool with ``jobs > 1``), shows a progress bar, and returns the
results of the items that succeeded together with one :class:`~schemas.status.StatusRecord` per
item. An exception in one item fails that item only; the reason names the exception.
``on_done`` sees each result as soon as it is ready (in completion order), so a stage can write
finished work incrementally instead of holding everything until the end.
"""
from __future__ import annotations

import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Callable, Iterable, Sequence

from tqdm.auto import tqdm

from schemas.status import StatusRecord


def _call(fn: Callable, item: Any) -> tuple[bool, Any, str, float]:
    start = time.perf_counter()
    try:
        return True, fn(item), "", time.perf_counter() - start
    except Exception as exc:  # one bad item must not end the run
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {tb[-1].filename.split('/')[-1]}:{tb[-1].lineno})" if tb else ""
        return False, None, f"{type(exc).__name__}: {exc}{where}", time.perf_counter() - start


def run_stage(
    items: Sequence[Any],
    fn: Callable[[Any], Any],
    stage: str,
    name_of: Callable[[Any], str] = str,
    jobs: int = 1,
    progress: bool = True,
    on_done: Callable[[int, bool, Any], None] | None = None,
) -> tuple[list[Any], list[StatusRecord]]:
    """Apply ``fn`` to each item; return (results in item order, status records).

    Args:
        items: the inputs.
        fn: the per-item stage function (must be picklable when ``jobs > 1``).
        stage: stage name written in the status records.
        name_of: the asset name of an item, for the status records.
        jobs: worker processes; 1 runs in this process.
        progress: show a progress bar.
        on_done: called in this process as ``on_done(index, ok, result)`` when an item finishes
            (``result`` None for a failed item).
    """
    if jobs < 1:
        raise ValueError(f"jobs: expected >= 1, got {jobs}")
    outcomes: list[tuple[bool, Any, str, float] | None] = [None] * len(items)
    bar = tqdm(total=len(items), desc=stage, unit="item", disable=not progress)

    def finished(i: int, outcome) -> None:
        outcomes[i] = outcome
        bar.update(1)
        if on_done is not None:
            on_done(i, outcome[0], outcome[1])

    if jobs == 1:
        for i, item in enumerate(items):
            finished(i, _call(fn, item))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_call, fn, item): i for i, item in enumerate(items)}
            for fut in as_completed(futures):
                finished(futures[fut], fut.result())
    bar.close()
    results, statuses = [], []
    for item, (ok, result, reason, seconds) in zip(items, outcomes):
        statuses.append(StatusRecord(name_of(item), stage, "ok" if ok else "failed", reason, seconds))
        if ok:
            results.append(result)
    return results, statuses


def summarize_statuses(statuses: Iterable[StatusRecord]) -> str:
    """One line per failure and a count line, for printing at the end of a stage."""
    statuses = list(statuses)
    failed = [s for s in statuses if s.status == "failed"]
    lines = [f"  FAILED {s.asset} [{s.stage}]: {s.reason}" for s in failed]
    lines.append(f"{len(statuses) - len(failed)} ok, {len(failed)} failed")
    return "\n".join(lines)
