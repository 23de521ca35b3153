"""The ingest job protocol between the runner and a Blender child, one module both sides import.

The parent writes one JSON line a job (:func:`job_line`: ``asset``, ``out``, ``options``); the child
writes ``OUT.npz`` and then, last and atomically, ``OUT.json`` (:func:`result_path`: ``status``,
``reason``, ...), and prints ``DONE_MARKER OUT``. A job counts as done only by its files
(:func:`run_job`). Standard library only at import time: the child imports this next to bpy.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

DONE_MARKER = "@@mimicbench-ingest-done@@"  # the child prints it with the output path after each job


def job_line(asset: str, out_npz: str, options: dict | None) -> str:
    """The JSON line that asks a child to ingest ``asset`` into ``out_npz`` (no newline)."""
    return json.dumps({"asset": asset, "out": out_npz, "options": options})


def result_path(out_npz: str | Path) -> Path:
    """``OUT.json`` of ``OUT.npz``: the job's result, written last."""
    return Path(out_npz).with_suffix(".json")


def remove_outputs(out_npz: Path) -> None:
    """Delete whatever a job wrote (final or partial files)."""
    stem = out_npz.with_suffix("")
    for p in (out_npz, stem.with_suffix(".json"), Path(str(out_npz) + ".part.npz"), Path(str(stem) + ".json.part")):
        if p.exists():
            p.unlink()


def status_of(result_file: Path) -> str:
    """The ``status`` a result file records, "" when it is missing or unreadable."""
    try:
        return json.loads(result_file.read_text()).get("status", "")
    except (OSError, ValueError):
        return ""


def run_job(worker, asset: Path, out_npz: Path, options: dict, timeout: float):
    """Ingest one asset with ``worker`` (a :class:`~mimicbench.datagen.ingest.blender_pool.BlenderWorker`);
    return its StatusRecord (failed jobs leave no files)."""
    from mimicbench.schemas.status import StatusRecord  # here, not at the top: the child imports this module

    start = time.perf_counter()
    remove_outputs(out_npz)
    finished, reason = worker.run(str(asset), str(out_npz), options, timeout)
    seconds = time.perf_counter() - start
    result_file = result_path(out_npz)
    if not finished or not result_file.exists() or not out_npz.exists() and status_of(result_file) == "ok":
        remove_outputs(out_npz)
        return StatusRecord(str(asset), "ingest", "failed", reason or "the Blender job wrote no result", seconds)
    result = json.loads(result_file.read_text())
    if result["status"] != "ok":
        remove_outputs(out_npz)
        return StatusRecord(str(asset), "ingest", "failed", result["reason"], seconds)
    return StatusRecord(str(asset), "ingest", "ok", "", seconds)
