"""One batch of cases of one protocol through a method, scored: the step every engine runs.

:func:`evaluate_batch` is what the single-process loop (:mod:`mimicbench.benchmark.evaluator`) and a Ray task
(:mod:`mimicbench.benchmark.ray_runner`) call; :func:`result_row` is the one way a case becomes a result row.
"""
from __future__ import annotations

from mimicbench.benchmark.protocols import DEFAULT_PROTOCOLS, answers, get_protocol
from mimicbench.benchmark.protocols.base import EvalData
from mimicbench.benchmark.request import MotionRequest, TransferRequest, mesh_only
from mimicbench.benchmark.scoring import check_prediction
from mimicbench.benchmark.worker import InProcessRunner
from mimicbench.schemas.result import APPAREL_METRICS, FORWARD_METRICS, NOT_SUPPORTED, ResultRecord


def _call(method, requests: list[TransferRequest], sizes: list):
    """Run a batch through a runner (:mod:`mimicbench.benchmark.worker`; a bare method runs in process); on a
    failure retry one by one. Returns [(array | None, error | None, seconds)]. ``sizes`` holds each
    answer's vertex count, or its whole shape ((F, N, 3) for a :class:`MotionRequest`)."""
    runner = method if hasattr(method, "run_batch") else InProcessRunner(method, setup=False)
    outcome = runner.run_batch(requests)
    error = outcome.error
    if error is None and len(outcome.outputs) != len(requests):
        error = f"method returned {len(outcome.outputs)} outputs for {len(requests)} requests"
    if error is not None:
        if len(requests) == 1:
            return [(None, error, outcome.seconds)]
        results = []
        for req, n in zip(requests, sizes):
            results.extend(_call(runner, [req], [n]))
        return results
    per = outcome.seconds / len(requests)
    results = []
    for out, n in zip(outcome.outputs, sizes):
        try:
            results.append((check_prediction(out, n), None, per))
        except ValueError as exc:
            results.append((None, str(exc), per))
    return results


def result_row(case, method, status, error, seconds, metrics=None) -> ResultRecord:
    m = metrics or {}
    return ResultRecord(case.case_id, case.protocol, method.metadata.name, method.metadata.version, status, error,
                        float(seconds), m.get("pmd"), m.get("pmd_squared"), m.get("els"), m.get("els_forward"),
                        case.source_category, case.target_category, pmd_height=m.get("pmd_height"),
                        pmd_extent=m.get("pmd_extent"), pmd_aligned=m.get("pmd_aligned"),
                        **{k: m.get(k) for k in APPAREL_METRICS + FORWARD_METRICS})


def supports(method, protocol: str) -> bool:
    """Whether the method's metadata lists ``protocol``."""
    return answers(getattr(method.metadata, "protocols", DEFAULT_PROTOCOLS), protocol)


def evaluate_batch(method, protocol, cases, data: EvalData, samples=None) -> list[ResultRecord]:
    """Score one batch of cases of one protocol (a :class:`BenchmarkProtocol` or its name);
    ``samples`` (a :class:`mimicbench.benchmark.samples.SampleSink`) keeps the predictions of the sampled
    cases for pictures.

    A method whose metadata does not list the protocol gets ``not_supported`` rows and is not
    called. A method whose metadata says ``reads_rig=False`` gets every transfer request through
    :func:`mimicbench.benchmark.request.mesh_only` (forward and return legs alike); the protocol scores
    with its own full rigs.
    """
    if isinstance(protocol, str):
        protocol = get_protocol(protocol)
    if not supports(method, protocol.name):
        reason = f"{method.metadata.name} does not support the {protocol.name} protocol (metadata.protocols)"
        return [result_row(c, method, NOT_SUPPORTED, reason, 0.0) for c in cases]

    strip = not getattr(method.metadata, "reads_rig", True)  # a mesh-only method gets no rig (scores use ours)

    def call(requests):
        requests = [mesh_only(r) for r in requests] if strip else list(requests)
        return _call(method, requests, [r.expected_shape if isinstance(r, MotionRequest) else
                                        len(r.target.vertices) for r in requests])

    call.method_tags = tuple(getattr(method.metadata, "tags", ()))  # e.g. an ablation that reads the GT mask

    outcomes = protocol.evaluate(cases, data, call)
    if samples is not None:  # predictions of a few sampled cases, for the leaderboard's pictures
        for leg in ("forward", "returned"):
            kept = [o for o in outcomes if leg in o.outputs]
            if kept:
                samples.keep([o.case for o in kept], [o.outputs[leg] for o in kept], leg=leg)
    return [result_row(o.case, method, o.status, o.error, o.seconds, o.metrics) for o in outcomes]
