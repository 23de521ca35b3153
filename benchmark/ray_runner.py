"""``bench run --engine ray``: batches of cases as Ray tasks, for CPU-bound methods and many small cases.

GPU methods keep ``torchrun`` (one rank a GPU, :mod:`benchmark.evaluator`). With the Ray engine,
each batch of ``--batch-size`` cases of one protocol is one task (1 CPU, retried by Ray when its
worker dies). A Ray worker process builds the method once from its import path (``module:Class``,
as :mod:`benchmark.worker` does) and calls ``setup(device)`` once, loads the dataset once, and
scores its batches exactly as the in-process runner does, keeping the sampled cases' predictions
for the leaderboard's pictures. The driver appends the rows in case order, so the results rows
are those of a local run (only ``seconds`` differ, as between any two runs).

What the worker-process runner gives and Ray does not: a per-case timeout (a hanging method
holds its task; cancel the run and use the local engine to find it). A method raising, returning
NaN or a wrong shape fails its case as usual; a task whose worker dies on every retry fails the
cases of its batch with Ray's error.
"""
from __future__ import annotations

import importlib
from functools import partial
from typing import Sequence

from benchmark.protocols import get_protocol

_METHODS: dict = {}  # per Ray worker process: import path -> method after setup
_DATA: dict = {}  # per Ray worker process: dataset folder -> EvalData


def _method(path: str, device: str):
    key = (path, device)
    if key not in _METHODS:
        module, qualname = path.split(":", 1)
        obj = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
        method = obj()
        method.setup(device)
        method.on_distributed_init(0, 1)
        _METHODS[key] = method
    return _METHODS[key]


def _data(dataset: str):
    if dataset not in _DATA:
        from benchmark.protocols.base import EvalData

        _DATA.clear()  # one dataset at a time per worker
        _DATA[dataset] = EvalData.load(dataset)
    return _DATA[dataset]


def ray_path(method) -> str:
    """The import path a Ray worker builds ``method`` from; ValueError when it has none."""
    from benchmark.worker import import_path

    path = import_path(method)
    if path is None:
        raise ValueError(f"{method.metadata.name}: its class cannot be imported by another process (defined in "
                         f"__main__ or inside a function); run it with the local engine")
    return path


def score_batch(cases: Sequence, method_path: str, device: str, dataset: str, protocol: str, samples=None) -> list:
    """ResultRecords of one batch of cases of one protocol (the Ray task's body)."""
    from benchmark.evaluator import evaluate_batch

    return evaluate_batch(_method(method_path, device), get_protocol(protocol), list(cases), _data(dataset), samples)


def evaluate_on_engine(engine, method, method_path: str, protocol: str, todo: Sequence, dataset, device: str,
                       batch_size: int, samples, on_rows, progress: bool = True) -> None:
    """Score ``todo`` cases of ``protocol`` in batches on ``engine``; ``on_rows(rows)`` in case order.

    A batch whose task failed for good (its worker died on every retry) gives ``failed`` rows
    with the engine's reason.
    """
    from benchmark.evaluator import _row
    from datagen.stage_runner import run_stage
    from mimicbench.engines import TaskResources

    batches = [list(todo[i:i + batch_size]) for i in range(0, len(todo), batch_size)]
    fn = partial(score_batch, method_path=method_path, device=device, dataset=str(dataset), protocol=protocol,
                 samples=samples)
    _, statuses = run_stage(batches, fn, f"{method.metadata.name}/{protocol}", name_of=lambda b: b[0].case_id,
                            progress=progress, on_done=lambda k, ok, rows: ok and on_rows(rows), engine=engine,
                            ordered=True, keep_results=False, resources=TaskResources(num_cpus=1))
    for batch, status in zip(batches, statuses):
        if status.status != "ok":
            on_rows([_row(c, method, "failed", f"batch task failed: {status.reason}", 0.0) for c in batch])
