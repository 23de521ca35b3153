"""``bench run --engine ray``: batches of cases as Ray tasks, for CPU-bound methods and many small cases.

GPU methods keep ``torchrun`` (one rank a GPU, :mod:`mimicbench.benchmark.evaluator`). With the Ray engine,
each batch of ``--batch-size`` cases of one protocol is one task (1 CPU, retried by Ray when its
worker dies). A Ray worker process builds the method once from its import path (``module:Class``,
as :mod:`mimicbench.benchmark.worker` does), loads the dataset once, and scores its batches through the
same runner as the local engine: a :class:`mimicbench.benchmark.worker.WorkerRunner` (a child process of
the Ray worker that runs ``setup(device)`` once) with the per-case timeout, or with
``in_process`` the method itself in the Ray worker (no timeout, no crash isolation). The sampled
cases' predictions are kept for the leaderboard's pictures. The driver appends the rows in case
order, so the results rows are those of a local run (only ``seconds`` differ, as between any two
runs).

A case over its time (a batch of B gets ``B x case_timeout``, then its cases are retried one at
a time), a method raising, returning NaN or a wrong shape, or a crash of the method's process
fails its case with the same reason the local engine writes ("timed out after 600 s"); the Ray
task goes on with a fresh method process. A task whose Ray worker dies on every retry fails the
cases of its batch with Ray's error.
"""
from __future__ import annotations

from functools import partial
from typing import Sequence

from mimicbench.benchmark.protocols import get_protocol
from mimicbench.runtime.registry import load_target

_RUNNERS: dict = {}  # per Ray worker process: (import path, device, timeout, in process) -> runner
_DATA: dict = {}  # per Ray worker process: dataset folder -> EvalData


def _runner(path: str, device: str, case_timeout: float, in_process: bool):
    """This Ray worker's runner of the method at ``path``, built on first use and kept for later batches."""
    from mimicbench.benchmark.worker import InProcessRunner, WorkerRunner

    key = (path, device, case_timeout, in_process)
    if key not in _RUNNERS:
        method = load_target(path)()
        _RUNNERS[key] = (InProcessRunner(method, device) if in_process
                         else WorkerRunner(method, path, device, case_timeout=case_timeout))
    return _RUNNERS[key]


def _data(dataset: str):
    if dataset not in _DATA:
        from mimicbench.benchmark.protocols.base import EvalData

        _DATA.clear()  # one dataset at a time per worker
        _DATA[dataset] = EvalData.load(dataset)
    return _DATA[dataset]


def ray_path(method) -> str:
    """The import path a Ray worker builds ``method`` from; ValueError when it has none."""
    from mimicbench.benchmark.worker import import_path

    path = import_path(method)
    if path is None:
        raise ValueError(f"{method.metadata.name}: its class cannot be imported by another process (defined in "
                         f"__main__ or inside a function); run it with the local engine")
    return path


def score_batch(cases: Sequence, method_path: str, device: str, dataset: str, protocol: str, samples=None,
                case_timeout: float = 600.0, in_process: bool = False) -> list:
    """ResultRecords of one batch of cases of one protocol (the Ray task's body)."""
    from mimicbench.benchmark.batch import evaluate_batch

    runner = _runner(method_path, device, float(case_timeout), in_process)
    return evaluate_batch(runner, get_protocol(protocol), list(cases), _data(dataset), samples)


def evaluate_on_engine(engine, method, method_path: str, protocol: str, todo: Sequence, dataset, device: str,
                       batch_size: int, samples, on_rows, progress: bool = True, case_timeout: float = 600.0,
                       in_process: bool = False) -> None:
    """Score ``todo`` cases of ``protocol`` in batches on ``engine``; ``on_rows(rows)`` in case order.

    ``case_timeout`` (seconds a case may take) and ``in_process`` mean what they mean for the
    local engine (:func:`mimicbench.benchmark.evaluator.run_benchmark`).

    A batch whose task failed for good (its worker died on every retry) gives ``failed`` rows
    with the engine's reason.
    """
    from mimicbench.benchmark.batch import result_row
    from mimicbench.datagen.stage_runner import run_stage
    from mimicbench.engines import TaskResources

    batches = [list(todo[i:i + batch_size]) for i in range(0, len(todo), batch_size)]
    fn = partial(score_batch, method_path=method_path, device=device, dataset=str(dataset), protocol=protocol,
                 samples=samples, case_timeout=case_timeout, in_process=in_process)
    _, statuses = run_stage(batches, fn, f"{method.metadata.name}/{protocol}", name_of=lambda b: b[0].case_id,
                            progress=progress, on_done=lambda k, ok, rows: ok and on_rows(rows), engine=engine,
                            ordered=True, keep_results=False, resources=TaskResources(num_cpus=1))
    for batch, status in zip(batches, statuses):
        if status.status != "ok":
            on_rows([result_row(c, method, "failed", f"batch task failed: {status.reason}", 0.0) for c in batch])
