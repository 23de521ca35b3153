"""Run methods on benchmark cases: ``mimicbench bench run``.

Cases are sharded by rank when launched by ``torchrun`` (``RANK``/``WORLD_SIZE``; gloo on CPU,
nccl on GPU), each rank appends its own result parts, and rank 0 aggregates once after a
barrier. A re-run computes only the cases without a row. A method that raises, returns NaN or a
wrong shape fails that case (the batch is retried one request at a time to find which) and the
run goes on.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from tqdm.auto import tqdm

from benchmark.registry import get_method
from benchmark.request import TransferRequest
from benchmark.results import append_results, done_case_ids, method_dir, write_run_info
from benchmark.rigs import load_characters
from benchmark.samples import SampleSink
from benchmark.scoring import check_prediction, score_cycle, score_h2h
from mimicbench.skinning import linear_blend_skinning
from schemas.result import ResultRecord
from schemas.shards import has_table, read_records

PROTOCOLS = ("h2h", "cct")


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
    """Cases of each protocol, in stored order; raises if ``bench cases`` has not been run."""
    out = {}
    for p in protocols:
        if p not in PROTOCOLS:
            raise ValueError(f"unknown protocol {p!r}; expected one of {', '.join(PROTOCOLS)}")
        if not has_table(dataset, "cases", p):
            raise FileNotFoundError(f"{dataset}: no {p} cases; run `mimicbench bench cases {dataset}` first")
        out[p] = read_records(dataset, "cases", p)
    return out


def _pairs_lookup(dataset) -> dict[tuple[str, str], np.ndarray]:
    if not has_table(dataset, "pairs"):
        return {}
    return {(r.source_id, r.target_id): r.m_sink for r in read_records(dataset, "pairs")}


def _call(method, requests: list[TransferRequest], sizes: list[int]):
    """Run a batch; on an exception retry one by one. Returns [(array | None, error | None, seconds)]."""
    start = time.perf_counter()
    try:
        outputs = method.transfer(requests)
        if len(outputs) != len(requests):
            raise RuntimeError(f"method returned {len(outputs)} outputs for {len(requests)} requests")
        per = (time.perf_counter() - start) / len(requests)
        results = []
        for out, n in zip(outputs, sizes):
            try:
                results.append((check_prediction(out, n), None, per))
            except ValueError as exc:
                results.append((None, str(exc), per))
        return results
    except Exception:
        if len(requests) == 1:
            import traceback

            exc_text = traceback.format_exc(limit=1).strip().splitlines()[-1]
            return [(None, f"method raised: {exc_text}", time.perf_counter() - start)]
        results = []
        for req, n in zip(requests, sizes):
            results.extend(_call(method, [req], [n]))
        return results


def _row(case, method, status, error, seconds, metrics=None) -> ResultRecord:
    m = metrics or {}
    return ResultRecord(case.case_id, case.protocol, method.metadata.name, method.metadata.version, status, error,
                        float(seconds), m.get("pmd"), m.get("pmd_squared"), m.get("els"), m.get("els_forward"),
                        case.source_category, case.target_category)


def _posed(char, transforms):
    r = char.rig
    return linear_blend_skinning(r.vertices, r.keypoints, r.weights, transforms)


def evaluate_batch(method, cases, chars, pairs, samples=None) -> list[ResultRecord]:
    """Score one batch of cases (one protocol) and return their rows; ``samples`` (a
    :class:`benchmark.samples.SampleSink`) keeps the predictions of the sampled cases for pictures."""
    protocol = cases[0].protocol
    src = [chars[c.source_id] for c in cases]
    tgt = [chars[c.target_id] for c in cases]
    posed_src = [_posed(s, c.source_transforms) for s, c in zip(src, cases)]

    def request(a, posed, b, case):
        extras = {}
        if (a.rig.character_id, b.rig.character_id) in pairs:
            k1, k2 = len(a.rig.parents), len(b.rig.parents)
            extras["m_sink"] = np.asarray(pairs[(a.rig.character_id, b.rig.character_id)]).reshape(k1, k2)
        return TransferRequest(a.rig, posed, b.rig, case.case_id, extras)

    fwd = _call(method, [request(s, p, t, c) for s, p, t, c in zip(src, posed_src, tgt, cases)],
                [len(t.rig.vertices) for t in tgt])
    if samples is not None:  # predictions of a few sampled cases, for the leaderboard's pictures
        samples.keep(cases, fwd)
    rows = []
    if protocol == "h2h":
        for c, t, (pred, err, sec) in zip(cases, tgt, fwd):
            if err:
                rows.append(_row(c, method, "failed", err, sec))
            else:
                rows.append(_row(c, method, "ok", None, sec, score_h2h(pred, _posed(t, c.target_transforms), t)))
        return rows
    ok = [i for i, (pred, err, _) in enumerate(fwd) if err is None]
    back = _call(method, [request(tgt[i], fwd[i][0], src[i], cases[i]) for i in ok],
                 [len(src[i].rig.vertices) for i in ok]) if ok else []
    back_of = dict(zip(ok, back))
    if samples is not None:
        samples.keep([cases[i] for i in ok], back, leg="returned")
    for i, c in enumerate(cases):
        pred, err, sec = fwd[i]
        if err:
            rows.append(_row(c, method, "failed", f"forward leg: {err}", sec))
            continue
        ret, err2, sec2 = back_of[i]
        if err2:
            rows.append(_row(c, method, "failed", f"return leg: {err2}", sec + sec2))
        else:
            rows.append(_row(c, method, "ok", None, sec + sec2, score_cycle(ret, posed_src[i], pred, src[i], tgt[i])))
    return rows


def run_benchmark(dataset, methods: Sequence[str], protocols: Sequence[str] = PROTOCOLS, out="results",
                  device: str = "cpu", batch_size: int = 16, progress: bool = True,
                  retry_failed: bool = False) -> dict:
    """Evaluate ``methods`` on the dataset's cases; returns a summary (rank 0 aggregates).

    Args:
        dataset: dataset folder with ``characters``, ``motions`` and ``cases`` tables.
        methods: registered method names.
        protocols: subset of ``h2h``, ``cct``.
        out: results folder; rows go to ``out/<method>/<version>/``.
        device: passed to each method's ``setup``.
        batch_size: requests per ``transfer`` call.
        retry_failed: also re-run cases whose stored row failed (default: only missing ones).
    """
    instances = [get_method(m) for m in methods]  # fail fast on unknown names
    cases = load_cases(dataset, protocols)
    chars = load_characters(dataset)
    pairs = _pairs_lookup(dataset)
    ctx = DistributedContext.from_env(device)
    counts = {"computed": 0, "skipped": 0, "failed": 0}
    try:
        if ctx.rank == 0:
            write_run_info(out, {"dataset": str(dataset), "protocols": {p: len(c) for p, c in cases.items()},
                                 "methods": {m.metadata.name: m.metadata.version for m in instances}})
        for method in instances:
            method.setup(device)
            method.on_distributed_init(ctx.rank, ctx.world_size)
            folder = method_dir(out, method.metadata.name, method.metadata.version)
            done = done_case_ids(folder, include_failed=not retry_failed) if folder.exists() else set()
            samples = SampleSink(folder, cases)
            for protocol, plist in cases.items():
                mine = [c for i, c in enumerate(plist) if i % ctx.world_size == ctx.rank]
                todo = [c for c in mine if c.case_id not in done]
                counts["skipped"] += len(mine) - len(todo)
                bar = tqdm(total=len(todo), desc=f"{method.metadata.name}/{protocol}", unit="case",
                           disable=not progress or not todo)
                for start in range(0, len(todo), batch_size):
                    rows = evaluate_batch(method, todo[start:start + batch_size], chars, pairs, samples)
                    append_results(folder, rows, ctx.rank)
                    counts["computed"] += len(rows)
                    counts["failed"] += sum(r.status != "ok" for r in rows)
                    bar.update(len(rows))
                bar.close()
            method.on_run_end()
        ctx.barrier()
    finally:
        ctx.close()
    summary = {"rank": ctx.rank, "world_size": ctx.world_size, **counts}
    if ctx.rank == 0:
        from benchmark.aggregate import aggregate

        summary["aggregate"] = aggregate(out)
    return summary
