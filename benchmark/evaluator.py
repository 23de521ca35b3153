"""Run methods on benchmark cases: ``mimicbench bench run``.

Cases are sharded by rank when launched by ``torchrun`` (``RANK``/``WORLD_SIZE``; gloo on CPU,
nccl on GPU), each rank appends its own result parts, and rank 0 aggregates once after a
barrier. A re-run computes only the cases without a row. A method that raises, returns NaN or a
wrong shape, writes into its (read-only) input, hangs past the per-case timeout or kills its
worker process fails that case (the batch is retried one request at a time to find which) and
the run goes on; see :mod:`mimicbench.benchmark.worker` for the worker process and :mod:`mimicbench.benchmark.provenance`
for the fingerprints that keep results, cases and dataset together.

The evaluator knows no protocol by name: each protocol module (:mod:`mimicbench.benchmark.protocols`) builds
its requests and scores, and calls the method only through the ``call`` it is handed here
(:func:`mimicbench.benchmark.batch.evaluate_batch`). A method whose metadata does not list a protocol gets ``not_supported`` rows.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Sequence

from tqdm.auto import tqdm

from mimicbench.benchmark.batch import evaluate_batch
from mimicbench.benchmark.protocols import DEFAULT_PROTOCOLS, get_protocol
from mimicbench.benchmark.protocols.base import EvalData
from mimicbench.benchmark.provenance import (check_cases_current, check_method_folder, check_results_folder,
                                  dataset_fingerprints, method_meta, write_method_meta)
from mimicbench.benchmark.ray_runner import evaluate_on_engine, ray_path
from mimicbench.benchmark.registry import LoadError, check_method_names, get_method
from mimicbench.benchmark.results import append_results, done_case_ids, method_dir, write_run_info
from mimicbench.benchmark.samples import SampleSink
from mimicbench.benchmark.worker import open_runner
from mimicbench.schemas.result import NOT_SUPPORTED
from mimicbench.schemas.dataset import Dataset


@dataclass
class DistributedContext:
    rank: int = 0
    world_size: int = 1
    initialised_here: bool = False

    @classmethod
    def from_env(cls, device: str) -> "DistributedContext":
        world = int(os.environ.get("WORLD_SIZE", "1"))
        rank = int(os.environ.get("RANK", "0"))
        if world <= 1:
            return cls()
        import torch.distributed as dist

        here = False
        if not dist.is_initialized():
            dist.init_process_group(backend="nccl" if device.startswith("cuda") else "gloo")
            here = True
        return cls(rank, world, here)

    def barrier(self) -> None:
        if self.world_size > 1:
            import torch.distributed as dist

            dist.barrier()

    def close(self) -> None:
        if self.initialised_here:
            import torch.distributed as dist

            dist.destroy_process_group()


def load_cases(dataset, protocols: Sequence[str]):
    """Cases of each protocol, in stored order; raises if ``bench cases`` has not been run.
    ``dataset``: a :class:`~mimicbench.schemas.dataset.Dataset` or its path."""
    dataset = Dataset.of(dataset)
    out = {}
    for p in protocols:
        get_protocol(p)  # raises on an unknown name
        if not dataset.has_table("cases", p):
            raise FileNotFoundError(f"{dataset}: no {p} cases; run `mimicbench bench cases {dataset}` first")
        out[p] = dataset.records("cases", p)
    return out


def check_run_options(methods: Sequence[str], batch_size: int, case_timeout: float) -> None:
    """Raise ValueError saying what is allowed when a run option is out of range."""
    if not methods:
        raise ValueError("methods: expected at least one method name (see `mimicbench bench methods`)")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch_size: expected an integer >= 1, got {batch_size!r}")
    if not case_timeout > 0:
        raise ValueError(f"case_timeout: expected seconds > 0, got {case_timeout!r}")


def run_benchmark(dataset, methods: Sequence[str], protocols: Sequence[str] = DEFAULT_PROTOCOLS, out="results",
                  device: str = "cpu", batch_size: int = 16, progress: bool = True,
                  retry_failed: bool = False, case_timeout: float = 600.0, in_process: bool = False,
                  engine=None) -> dict:
    """Evaluate ``methods`` on the dataset's cases; returns a summary (rank 0 aggregates).

    Args:
        dataset: dataset folder with ``characters``, ``motions`` and ``cases`` tables.
        methods: registered method names.
        protocols: protocol names (:func:`mimicbench.benchmark.protocols.available_protocols`).
        out: results folder; rows go to ``out/<method>/<version>/`` with a ``meta.json``.
        device: passed to each method's ``setup``.
        batch_size: requests per ``transfer`` call (>= 1).
        retry_failed: also re-run cases whose stored row failed (default: only missing ones).
        case_timeout: seconds a request may take in the worker process (> 0).
        in_process: call methods in this process (faster start, no timeout, no crash isolation).
        engine: a :class:`mimicbench.engines.RayEngine` runs each batch as a Ray task
            (:mod:`mimicbench.benchmark.ray_runner`); None or a local engine keeps the worker processes.

    A method whose entry cannot be imported (:class:`~mimicbench.runtime.registry.LoadError`, e.g. a plug-in
    missing a module) is not run: the summary's ``unavailable`` maps its name to the reason.

    Raises:
        UnknownName: a method or protocol name no entry has (before anything is loaded or written).
        ValueError: an option out of range.
        ProvenanceError: the cases were built from another state of the dataset, or ``out``
            holds rows made from another dataset state (nothing is written then).
    """
    from mimicbench.schemas.spawn_guard import leave_if_reimporting_main

    leave_if_reimporting_main("a benchmark run")  # a worker re-running an unguarded script: stop, write nothing
    check_run_options(methods, batch_size, case_timeout)
    check_method_names(methods)  # fail fast on unknown names
    instances, unavailable = [], {}
    for name in methods:  # a method that cannot be imported (a broken plug-in) is left out, the others run
        try:
            instances.append(get_method(name))
        except LoadError as exc:
            unavailable[name] = str(exc)
    check_cases_current(dataset)  # before the reader refuses stale cases, to name the fix
    dataset = Dataset.of(dataset)  # the manifest read once for cases, fingerprints and the evaluation data
    cases = load_cases(dataset, protocols)
    fingerprints = dataset_fingerprints(dataset, list(cases))
    check_results_folder(out, fingerprints)
    metas = [method_meta(m.metadata, dataset, fingerprints, m.weights_fingerprint()) for m in instances]
    for method, meta in zip(instances, metas):  # refuse before anything is written
        check_method_folder(method_dir(out, method.metadata.name, method.metadata.version), meta)
    on_ray = engine is not None and getattr(engine, "name", "local") != "local"
    data = None if on_ray else EvalData.load(dataset)
    ctx = DistributedContext.from_env(device)
    if on_ray and ctx.world_size > 1:
        raise ValueError("engine ray: run without torchrun (Ray spreads the cases itself)")
    counts = {"computed": 0, "skipped": 0, "failed": 0, NOT_SUPPORTED: 0}

    def tally(folder, rows) -> None:
        append_results(folder, rows, ctx.rank)
        counts["computed"] += len(rows)
        counts["failed"] += sum(r.status == "failed" for r in rows)
        counts[NOT_SUPPORTED] += sum(r.status == NOT_SUPPORTED for r in rows)

    try:
        if ctx.rank == 0:
            write_run_info(out, {"dataset": str(dataset), "protocols": {p: len(c) for p, c in cases.items()},
                                 "case_ids": {p: sorted(x.case_id for x in c) for p, c in cases.items()},
                                 "methods": {m.metadata.name: m.metadata.version for m in instances}})
        for method, meta in zip(instances, metas):
            folder = method_dir(out, method.metadata.name, method.metadata.version)
            if ctx.rank == 0:
                write_method_meta(folder, meta)
            done = done_case_ids(folder, include_failed=not retry_failed) if folder.exists() else set()
            samples = SampleSink(folder, cases)
            if on_ray:
                for name, plist in cases.items():
                    todo = [c for c in plist if c.case_id not in done]
                    counts["skipped"] += len(plist) - len(todo)
                    evaluate_on_engine(engine, method, ray_path(method), name, todo, dataset, device, batch_size,
                                       samples, lambda rows: tally(folder, rows), progress and bool(todo),
                                       case_timeout, in_process)
                continue
            runner = open_runner(method, device, ctx.rank, ctx.world_size, case_timeout, in_process)
            try:
                for name, plist in cases.items():
                    protocol = get_protocol(name)
                    mine = [c for i, c in enumerate(plist) if i % ctx.world_size == ctx.rank]
                    todo = [c for c in mine if c.case_id not in done]
                    counts["skipped"] += len(mine) - len(todo)
                    bar = tqdm(total=len(todo), desc=f"{method.metadata.name}/{name}", unit="case",
                               disable=not progress or not todo)
                    for start in range(0, len(todo), batch_size):
                        rows = evaluate_batch(runner, protocol, todo[start:start + batch_size], data, samples)
                        tally(folder, rows)
                        bar.update(len(rows))
                    bar.close()
            except BaseException:
                runner.abort()
                raise
            runner.close()
        ctx.barrier()
    finally:
        ctx.close()
    summary = {"rank": ctx.rank, "world_size": ctx.world_size, **counts, "unavailable": unavailable}
    if ctx.rank == 0:
        from mimicbench.benchmark.aggregate import aggregate

        summary["aggregate"] = aggregate(out)
    return summary
