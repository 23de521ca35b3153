"""The Ray engine: each chunk of items one Ray task, on a local Ray instance or a cluster.

Each task declares its resources (``num_cpus``, ``memory``) and is retried by Ray when its
worker dies (``max_retries``: a killed or crashed worker process, a lost node). The stage
function is put in the object store once and shared by every task. At most ``max_in_flight``
tasks run or wait at a time (default: twice the cluster's CPUs); results stream back as tasks
finish and the driver writes them (``run_stage`` restores item order where a stage needs it),
so the output is the same bytes as the local engine's. A task that still fails after its
retries (the worker died every time, a task over its memory) turns every item of its chunk into
a failed outcome naming Ray's error; the run goes on.

On a cluster (``address``), every node needs this package importable (the same install), and
the data folders on a file system every node sees.
"""
from __future__ import annotations

import logging
from typing import Any, Callable, Iterator, Sequence

from mimicbench.engines.base import Engine, Outcome, TaskResources, call_chunk, chunks_of

DEFAULT_MAX_RETRIES = 3
_REMOTE = None


def _remote_chunk():
    """The Ray remote function wrapping :func:`call_chunk` (made once, after ``import ray``)."""
    global _REMOTE
    if _REMOTE is None:
        import ray

        _REMOTE = ray.remote(call_chunk)
    return _REMOTE


def ensure_ray(address: str | None = None, num_cpus: int | None = None) -> None:
    """Connect to Ray: the running instance of this process if any, else ``address``, else start a local one.

    Args:
        address: a cluster address (``ray://host:10001``, ``host:6379`` or ``auto``); None starts a local
            instance with ``num_cpus`` CPUs (default: all of this machine's).
    """
    try:
        import ray
    except ImportError as exc:  # the optional extra
        raise RuntimeError("--engine ray needs Ray: pip install 'mimicbench[ray]'") from exc
    if ray.is_initialized():
        return
    if address:
        ray.init(address=address, logging_level=logging.WARNING)
    else:
        ray.init(num_cpus=num_cpus, include_dashboard=False, logging_level=logging.WARNING)


class RayEngine(Engine):
    """Ray tasks. ``address`` None starts (or reuses) a local Ray instance of ``num_cpus`` CPUs.

    ``runtime_env``: Ray's per-task runtime environment (e.g. ``{"env_vars": {...}}`` for variables
    the workers need that were not set when Ray started), or None for the cluster's own.
    """

    name = "ray"

    def __init__(self, address: str | None = None, num_cpus: int | None = None,
                 max_retries: int = DEFAULT_MAX_RETRIES, max_in_flight: int | None = None,
                 runtime_env: dict | None = None):
        if max_retries < 0:
            raise ValueError(f"max_retries: expected >= 0, got {max_retries}")
        if max_in_flight is not None and max_in_flight < 1:
            raise ValueError(f"max_in_flight: expected >= 1 or None, got {max_in_flight}")
        self.address, self.num_cpus = address, num_cpus
        self.max_retries, self.max_in_flight = max_retries, max_in_flight
        self.runtime_env = runtime_env

    def describe(self) -> str:
        return f"ray ({self.address or 'local instance'})"

    def imap(self, fn: Callable[[Any], Any], items: Sequence[Any], chunk: int = 1,
             resources: TaskResources = TaskResources()) -> Iterator[tuple[int, Outcome]]:
        import ray

        ensure_ray(self.address, self.num_cpus)
        if not items:
            return
        remote = _remote_chunk().options(num_cpus=resources.num_cpus, memory=resources.memory,
                                         max_retries=self.max_retries,
                                         **({"runtime_env": self.runtime_env} if self.runtime_env else {}))
        window = self.max_in_flight or max(2, 2 * int(ray.cluster_resources().get("CPU", 1)))
        fn_ref = ray.put(fn)
        pending = list(reversed(chunks_of(len(items), chunk)))
        running: dict = {}
        while pending or running:
            while pending and len(running) < window:
                rng = pending.pop()
                running[remote.remote(fn_ref, [items[i] for i in rng])] = rng
            done, _ = ray.wait(list(running), num_returns=1)
            for ref in done:
                rng = running.pop(ref)
                try:
                    outcomes = ray.get(ref)
                except ray.exceptions.RayError as exc:  # retries used up: the chunk's items fail, the run goes on
                    reason = f"{type(exc).__name__} after {self.max_retries} retries: {_first_line(exc)}"
                    outcomes = [Outcome(False, None, reason, 0.0) for _ in rng]
                for i, outcome in zip(rng, outcomes):
                    yield i, outcome


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:300] if text else type(exc).__name__
