"""Run a pipeline: each step's command function in turn, skipping finished steps, with a summary.

Each step calls its command's function with its options dataclass (:func:`~.spec.step_options`,
no command line in between); the :class:`~mimicbench.runtime.summary.StageSummary` it returns fills the
step's row of the summary. A step whose exit status is 0 is recorded as finished. One with 1 wrote its output but
some items failed (status rows: a character that would not build, a block of pairs whose worker
died on every retry): the pipeline goes on and the step is not recorded, so the next run retries
it (each stage resumes what it already wrote). Any other exit status, or a user error (printed as
``mimicbench: error: ...``), stops the pipeline; a re-run starts from that step.
"""
from __future__ import annotations

import os
import shlex
import shutil
import sys
import time
from dataclasses import dataclass

from tqdm.auto import tqdm

from mimicbench.pipeline.spec import Pipeline, step_argv, step_options
from mimicbench.pipeline.state import PipelineState, outputs_digest, step_fingerprint
from mimicbench.runtime.errors import USER_ERRORS, error_text
from mimicbench.runtime.summary import StageSummary, exit_code


@dataclass
class StepResult:
    """How one step went: ``status`` done / skipped / partial (items failed) / failed / not run."""

    name: str
    status: str
    seconds: float = 0.0
    command: str = ""
    note: str = ""
    summary: StageSummary | None = None


def run_pipeline(pipeline: Pipeline, progress: bool = True, force: tuple[str, ...] = ()) -> list[StepResult]:
    """Run the steps of ``pipeline`` in order; ``force`` names steps to run even when finished."""
    unknown = sorted(set(force) - {s.name for s in pipeline.steps})
    if unknown:
        raise ValueError(f"--force: no step named {unknown}; steps: {[s.name for s in pipeline.steps]}")
    calls = [step_options(step, pipeline) for step in pipeline.steps]  # all checked before any runs
    pipeline.workdir.mkdir(parents=True, exist_ok=True)
    state = PipelineState(pipeline)
    results: list[StepResult] = []
    bar = tqdm(total=len(pipeline.steps), desc=f"pipeline {pipeline.name}", unit="step", disable=not progress,
               position=0)
    stopped = False
    for i, (step, (func, options)) in enumerate(zip(pipeline.steps, calls), 1):
        argv = step_argv(step, pipeline)
        command = "mimicbench " + shlex.join(argv)
        if stopped:
            results.append(StepResult(step.name, "not run", command=command))
            continue
        bar.set_description(f"pipeline {pipeline.name} [{i}/{len(pipeline.steps)}] {step.name}")
        fingerprint = step_fingerprint(step, pipeline)
        if step.name not in force and state.is_done(step, fingerprint, outputs_digest(step, pipeline)):
            results.append(StepResult(step.name, "skipped", command=command, note="finished earlier, inputs unchanged"))
            bar.update(1)
            continue
        if progress:
            tqdm.write(f"[{i}/{len(pipeline.steps)}] {command}", file=sys.stderr)
        if step.restart and step.name in state.steps:  # it finished from other inputs: start its folders again
            for key, _ in step.spec.writes:
                for folder in step.folder(key, pipeline.workdir):
                    shutil.rmtree(folder, ignore_errors=True)
        state.forget(step)
        start = time.perf_counter()
        summary, note = None, ""
        try:
            summary = func(options)
        except KeyboardInterrupt:
            rc, note = 130, "interrupted; work already written is kept, re-run to resume"
        except USER_ERRORS as exc:
            if os.environ.get("MIMICBENCH_DEBUG", "") not in ("", "0"):
                raise
            print(f"mimicbench: error: {error_text(exc)}\n(run with --debug for the traceback)", file=sys.stderr)
            rc, note = 2, error_text(exc).splitlines()[0]
        else:
            rc = exit_code(summary)
            summary = summary if isinstance(summary, StageSummary) else None
        seconds = time.perf_counter() - start
        counts = "" if summary is None else f"{summary.ok} ok, {summary.failed} failed -> {summary.out}"
        if rc == 0:
            state.record(step, step_fingerprint(step, pipeline), outputs_digest(step, pipeline), seconds)
            results.append(StepResult(step.name, "done", seconds, command, counts, summary))
        elif rc == 1:
            results.append(StepResult(step.name, "partial", seconds, command, (counts + "; " if counts else "")
                                      + "re-run to retry the failed items (see the step's status rows)", summary))
        else:
            results.append(StepResult(step.name, "failed", seconds, command, note or f"exit status {rc}", summary))
            stopped = True
        bar.update(1)
    bar.close()
    return results


def format_summary(pipeline: Pipeline, results: list[StepResult]) -> str:
    """The table printed at the end: step, status, seconds, note (the step's counts and output folder)."""
    width = max(len(r.name) for r in results)
    lines = [f"pipeline {pipeline.name} in {pipeline.workdir} (engine {pipeline.engine}):"]
    for r in results:
        secs = f"{r.seconds:8.1f} s" if r.status in ("done", "partial", "failed") else " " * 10
        lines.append(f"  {r.name:<{width}}  {r.status:<8} {secs}  {r.note}".rstrip())
    counts = {s: sum(r.status == s for r in results) for s in ("done", "skipped", "partial", "failed", "not run")}
    lines.append("  " + ", ".join(f"{n} {s}" for s, n in counts.items() if n)
                 + f"; {sum(r.seconds for r in results):.1f} s")
    return "\n".join(lines)
