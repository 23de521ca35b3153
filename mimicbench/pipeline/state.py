"""What a pipeline has done: per step a fingerprint of what it read and a digest of what it wrote.

A step is skipped when its fingerprint (the step's options without engine settings, the
fingerprints of the tables it reads, and the versions of the code that makes its output: the
toolkit's, the stage's own version constants, a bench step's method versions) equals the one recorded when it last finished, and what it
wrote is still as it left it (so a deleted or rebuilt output is made again). The record lives in
``WORKDIR/.pipeline/<name>.json`` and is written atomically after each finished step, so a
pipeline killed at any point resumes with the next unfinished step.
"""
from __future__ import annotations

import importlib
import json
from pathlib import Path

import mimicbench

from mimicbench.pipeline.spec import ENGINE_KEYS, Pipeline, Step
from mimicbench.schemas.fingerprint import digest_of
from mimicbench.schemas.manifest import MANIFEST, atomic_write_bytes, load_manifest


def folder_digest(path: Path, tables: tuple[str, ...] | None) -> str:
    """Digest of a dataset's ``tables`` (from manifest.json: shard paths, rows, sha256), or of any
    file or folder (relative paths, sizes and modification times) when ``tables`` is None or the
    folder holds no dataset; ``"missing"`` for a path that does not exist."""
    if not path.exists():
        return "missing"
    if tables is not None and (path / MANIFEST).is_file():
        manifest = load_manifest(path)
        return digest_of({"complete": manifest.get("complete", True),
                          **{t: sorted((s["path"], s["rows"], s["sha256"])
                                       for s in manifest["tables"].get(t, {}).get("shards", [])) for t in tables}})
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file() and ".pipeline" not in p.parts)
    return digest_of([(str(p.relative_to(path)) if p != path else p.name, p.stat().st_size, p.stat().st_mtime_ns)
                      for p in files])


def _digests(step: Step, pipeline: Pipeline, which) -> dict:
    return {f"{key}:{p}": folder_digest(p, tables) for key, tables in which for p in step.folder(key, pipeline.workdir)}


def code_versions(step: Step) -> dict:
    """``{"toolkit": ..., "module:NAME": value, "method:NAME": version}``: the toolkit's version, the
    step kind's version constants, and for a bench step each named method's ``metadata.version``
    (an unknown method is left to the command, which names it)."""
    versions = {"toolkit": mimicbench.__version__}
    for ref in step.spec.versions:
        module, name = ref.split(":")
        versions[ref] = str(getattr(importlib.import_module(module), name))
    if step.kind == "bench":
        from mimicbench.benchmark.registry import METHODS, NameCollision, UnknownName

        names = step.options.get("methods") or []
        names = names if isinstance(names, list) else str(names).split(",")  # as the option's type reads it
        for name in (str(n).strip() for n in names):
            try:
                versions[f"method:{name}"] = str(METHODS.get(name).metadata.version)
            except (UnknownName, NameCollision, AttributeError, ImportError):
                versions[f"method:{name}"] = "unknown"
    return versions


def step_fingerprint(step: Step, pipeline: Pipeline) -> str:
    """Digest of the step's kind and options (engine settings left out), of the versions of its code
    (:func:`code_versions`) and of what it reads now."""
    options = {k: v for k, v in step.options.items() if k not in ENGINE_KEYS}
    return digest_of({"kind": step.kind, "options": options, "code": code_versions(step),
                      "reads": _digests(step, pipeline, step.spec.reads)})


def outputs_digest(step: Step, pipeline: Pipeline) -> str:
    """Digest of what the step writes, as it is now."""
    return digest_of(_digests(step, pipeline, step.spec.writes))


class PipelineState:
    """The record of finished steps of one pipeline in one workdir."""

    def __init__(self, pipeline: Pipeline):
        self.path = pipeline.workdir / ".pipeline" / f"{pipeline.name}.json"
        self.steps: dict = {}
        if self.path.is_file():
            try:
                self.steps = json.loads(self.path.read_text()).get("steps", {})
            except (json.JSONDecodeError, AttributeError):
                self.steps = {}  # an unreadable record only means every step is checked again

    def is_done(self, step: Step, fingerprint: str, outputs: str) -> bool:
        rec = self.steps.get(step.name) or {}
        return rec.get("fingerprint") == fingerprint and rec.get("outputs") == outputs

    def record(self, step: Step, fingerprint: str, outputs: str, seconds: float) -> None:
        self.steps[step.name] = {"fingerprint": fingerprint, "outputs": outputs, "seconds": round(seconds, 3)}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(self.path, (json.dumps({"steps": self.steps}, indent=2, sort_keys=True) + "\n").encode())

    def forget(self, step: Step) -> None:
        if self.steps.pop(step.name, None) is not None and self.path.parent.is_dir():
            atomic_write_bytes(self.path, (json.dumps({"steps": self.steps}, indent=2, sort_keys=True) + "\n").encode())


__all__ = ["PipelineState", "folder_digest", "outputs_digest", "step_fingerprint"]
