"""The stage skeleton every datagen stage runs through, and :func:`run_stage` for its items.

A stage declares a :class:`Stage`: its name, its params dataclass (every parameter that changes
its output), the input tables it reads, its per-item function and the tables it writes. A
:class:`StageRun` of it owns what every stage does the same way: the config and its fingerprint
(:func:`schemas.fingerprint.stage_config`), the refusal of an OUT folder holding a dataset made by
another stage, the config earlier rows were made under (reuse needs the same fingerprint), the
incomplete/complete marks, rows-per-shard (:func:`schemas.tables.rows_per_shard`), status rows,
tables copied untouched from the input, and validation. The resume rule they implement is written
once in ``schemas/FORMAT.md`` ("Stages and resume").

:func:`run_stage` calls the per-item function for every item through an engine
(:mod:`mimicbench.engines`: this process, a process pool with ``jobs > 1``, or Ray tasks), shows
a progress bar, and returns the results of the items that succeeded together with one
:class:`~schemas.status.StatusRecord` per item. An exception in one item fails that item only; the
reason names the exception. ``on_done`` sees each result as soon as it is ready, so a stage can
write finished work incrementally instead of holding everything until the end.
"""
from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from tqdm.auto import tqdm

from mimicbench.engines import Engine, LocalEngine, Outcome, TaskResources
from schemas.errors import DatasetError
from schemas.fingerprint import fingerprint_mismatch, stage_config, tables_fingerprint
from schemas.integrity import entry_path, verify_shard
from schemas.manifest import (MANIFEST, chmod_like_open, fsync_file, load_manifest_for_write, mark_complete,
                              mark_incomplete, save_manifest)
from schemas.shard_stream import ShardStream
from schemas.shards import has_table, write_records
from schemas.status import StatusRecord
from schemas.tables import rows_per_shard
from schemas.validate import validate_dataset


def run_stage(
    items: Sequence[Any],
    fn: Callable[[Any], Any],
    stage: str,
    name_of: Callable[[Any], str] = str,
    jobs: int = 1,
    progress: bool = True,
    on_done: Callable[[int, bool, Any], None] | None = None,
    engine: Engine | None = None,
    chunk: int = 1,
    resources: TaskResources = TaskResources(),
    ordered: bool = False,
    keep_results: bool = True,
) -> tuple[list[Any], list[StatusRecord]]:
    """Apply ``fn`` to each item; return (results in item order, status records).

    Args:
        items: the inputs.
        fn: the per-item stage function (must be picklable for a process pool or Ray).
        stage: stage name written in the status records.
        name_of: the asset name of an item, for the status records.
        jobs: worker processes of the local engine when ``engine`` is None; 1 runs in this process.
        progress: show a progress bar.
        on_done: called in this process as ``on_done(index, ok, result)`` when an item finishes
            (``result`` None for a failed item); in completion order, or in item order with ``ordered``.
        engine: where the work runs (:mod:`mimicbench.engines`); default ``LocalEngine(jobs)``.
        chunk: items per task (per-task overhead is paid once a chunk).
        resources: what each task asks the engine for (CPUs, memory).
        ordered: call ``on_done`` in item order (a finished item waits for those before it), so a
            stage that writes as it goes writes the same bytes on every engine.
        keep_results: False returns no results (``on_done`` has seen them): memory stays bounded.
    """
    if jobs < 1:
        raise ValueError(f"jobs: expected >= 1, got {jobs}")
    engine = engine or LocalEngine(jobs)
    outcomes: list[tuple[bool, str, float] | None] = [None] * len(items)
    kept: dict[int, Any] = {}
    waiting: dict[int, Outcome] = {}
    next_in_order = 0
    bar = tqdm(total=len(items), desc=stage, unit="item", disable=not progress)

    def deliver(i: int, outcome: Outcome) -> None:
        if on_done is not None:
            on_done(i, outcome.ok, outcome.result)

    for i, outcome in engine.imap(fn, items, chunk, resources):
        outcomes[i] = (outcome.ok, outcome.reason, outcome.seconds)
        if outcome.ok and keep_results:
            kept[i] = outcome.result
        bar.update(1)
        if not ordered:
            deliver(i, outcome)
            continue
        waiting[i] = outcome
        while next_in_order in waiting:
            deliver(next_in_order, waiting.pop(next_in_order))
            next_in_order += 1
    bar.close()
    results, statuses = [], []
    for i, (item, (ok, reason, seconds)) in enumerate(zip(items, outcomes)):
        statuses.append(StatusRecord(name_of(item), stage, "ok" if ok else "failed", reason, seconds))
        if ok and keep_results:
            results.append(kept[i])
    return results, statuses


def summarize_statuses(statuses: Iterable[StatusRecord]) -> str:
    """One line per failure and a count line, for printing at the end of a stage."""
    statuses = list(statuses)
    failed = [s for s in statuses if s.status == "failed"]
    lines = [f"  FAILED {s.asset} [{s.stage}]: {s.reason}" for s in failed]
    lines.append(f"{len(statuses) - len(failed)} ok, {len(failed)} failed")
    return "\n".join(lines)


NO_ROWS = "OUT holds no earlier rows"  # StageRun.previous's reason when there is nothing to reuse


def omitted_unless_set(default=None):
    """A params field left out of the stored config while it holds ``default`` (so configs made
    before the field existed keep their fingerprint)."""
    return dataclasses.field(default=default, metadata={"omit": default})


@dataclass(frozen=True)
class Stage:
    """What a datagen stage declares (see the module docstring).

    ``params``: a dataclass type; ``inputs``: the tables read from IN (those IN lacks are left
    out); ``item``: the per-item function; ``outputs``: the tables written; ``copies``: tables
    copied untouched from IN; ``made_by``: the output table whose config names the stage that
    made OUT (refusal, reuse).
    """

    name: str
    params: type
    inputs: tuple[str, ...]
    item: Callable
    outputs: tuple[str, ...]
    copies: tuple[str, ...] = ()
    made_by: str = "characters"
    out_name: str = "OUT_DATASET"  # how the CLI names the output folder, for messages
    generator: str | None = None  # the config's ``generator`` of datasets made before configs named their stage


class StageRun:
    """One run of ``stage`` with ``params`` from ``in_dir`` (None: no input; ``out_dir`` itself
    for a stage that adds tables to its input) into ``out_dir``.

    Refuses at once an ``out_dir`` holding a dataset that another stage made (nothing changed).
    """

    def __init__(self, stage: Stage, params, out_dir, in_dir=None, info: dict | None = None,
                 refuse_foreign: bool = True):
        if not isinstance(params, stage.params):
            raise TypeError(f"{stage.name}: params: expected {stage.params.__name__}, got {type(params).__name__}")
        self.stage, self.params, self.out_dir = stage, params, Path(out_dir)
        self.in_dir = None if in_dir is None else Path(in_dir)
        same = self.in_dir is not None and self.in_dir.resolve() == self.out_dir.resolve()
        inputs = [t for t in stage.inputs if self.in_dir is not None and has_table(self.in_dir, t)]
        self.config = stage_config({"stage": stage.name, **self.params_dict()},
                                   tables_fingerprint(self.in_dir, inputs) if inputs else {},
                                   inputs_from="." if same or self.in_dir is None else str(self.in_dir.resolve()),
                                   info=info)
        self.before: dict | None = None
        if refuse_foreign:
            self.refuse_foreign()

    def params_dict(self) -> dict:
        """The params as stored in the config; a field declared with :func:`omitted_unless_set`
        is left out while it holds its default; a value with ``to_json`` is stored as its JSON."""
        values = {f.name: getattr(self.params, f.name) for f in dataclasses.fields(self.params)
                  if "omit" not in f.metadata or getattr(self.params, f.name) != f.metadata["omit"]}
        return {k: v.to_json() if hasattr(v, "to_json") else v for k, v in values.items()}

    def manifest(self) -> dict | None:
        """OUT's manifest, or None when OUT holds no dataset yet."""
        return load_manifest_for_write(self.out_dir) if (self.out_dir / MANIFEST).exists() else None

    def refuse_foreign(self) -> None:
        """Raise DatasetError when OUT holds tables whose ``made_by`` config names another stage
        (and no run of this stage is pending there)."""
        manifest = self.manifest()
        if manifest is None or not manifest["tables"]:
            return
        made = manifest["configs"].get(self.stage.made_by) or {}
        if self.stage.name not in (made.get("stage"), (manifest.get("pending") or {}).get("stage")) \
                and (self.stage.generator is None or made.get("generator") != self.stage.generator):
            by = made.get("stage") or made.get("generator") or "another stage"
            raise DatasetError(f"{self.out_dir}: holds a dataset made by {by}, not by {self.stage.name}; choose an "
                               f"empty or new {self.stage.out_name} (nothing was changed)")

    def previous(self, pending: bool = True) -> tuple[dict | None, str | None]:
        """(the config OUT's rows were made under, why they cannot be reused: None when they can).

        The config of an unfinished run of this stage when ``pending`` and there is one, else that
        of OUT's ``made_by`` table; (None, :data:`NO_ROWS`) when OUT holds no rows of it.
        """
        manifest = self.manifest()
        if manifest is None or not manifest["tables"].get(self.stage.made_by):
            return None, NO_ROWS
        run = manifest.get("pending") or {}
        old = run.get("config") if pending and run.get("stage") == self.stage.name \
            else manifest["configs"].get(self.stage.made_by)
        return old, fingerprint_mismatch(old, self.config)

    def begin(self) -> None:
        """Mark OUT incomplete (``pending``: this stage and its config) until :meth:`finish`."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.before = self.manifest()
        mark_incomplete(self.out_dir, self.stage.name, self.config)

    def abandon(self) -> None:
        """Undo :meth:`begin` after a run that produced nothing: the old manifest, or no folder."""
        if self.before is not None:
            save_manifest(self.out_dir, self.before)
            return
        (self.out_dir / MANIFEST).unlink(missing_ok=True)
        for folder in [self.out_dir / t for t in self.stage.outputs] + [self.out_dir]:
            try:
                folder.rmdir()  # only when empty
            except OSError:
                pass

    def write(self, table: str, records, split: str, config: dict | None | str = "run") -> list[dict]:
        """Write one split of ``table``; return its entries. ``config``: stored for the table
        (``"run"``: the run's; None: the manifest's is left as it is, as for part shards, whose
        table gets the run's config in :meth:`finish`)."""
        return write_records(self.out_dir, table, list(records), split, rows_per_shard(table, self.stage.name),
                             config=self.config if config == "run" else config)

    def stream(self, table: str, split: str, config: dict | None | str = "run") -> ShardStream:
        """A :class:`ShardStream` of one split of ``table`` (``config`` as in :meth:`write`)."""
        return ShardStream(self.out_dir, table, split, rows_per_shard(table, self.stage.name),
                           self.config if config == "run" else config)

    def write_status(self, rows: list[StatusRecord], config: dict | None | str = "run") -> None:
        """The stage's status rows: split ``stage.name`` of the ``status`` table."""
        self.write("status", rows, self.stage.name, config)

    def copy_untouched(self) -> None:
        """Copy the ``copies`` tables from IN, verified shard by shard (see :func:`copy_table`)."""
        for table in self.stage.copies:
            copy_table(self.in_dir, self.out_dir, table)

    def finish(self, configs: Iterable[str] = ()) -> None:
        """Give the ``configs`` tables the run's config, mark OUT complete (one manifest write) and
        validate it (RuntimeError listing the problems)."""
        manifest = load_manifest_for_write(self.out_dir)
        manifest["configs"].update({t: self.config for t in configs})
        save_manifest(self.out_dir, manifest)
        mark_complete(self.out_dir)
        problems = validate_dataset(self.out_dir)
        if problems:
            raise RuntimeError(f"{self.stage.name} wrote an invalid dataset:\n" + "\n".join(problems))


def _copy_file(src: Path, dst: Path) -> None:
    """Copy ``src`` to ``dst`` through a temporary file (fsynced, umask mode) renamed into place."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{dst.name}.", suffix=".tmp", dir=dst.parent)
    os.close(fd)
    try:
        shutil.copyfile(src, tmp)
        fsync_file(tmp)
        chmod_like_open(tmp)
        os.replace(tmp, dst)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def copy_table(src: Path, dst: Path, table: str) -> None:
    """Make ``dst``'s ``table`` a verified copy of ``src``'s (or drop it when ``src`` has none).

    Every path is confined to its dataset folder and each source shard is checked against its
    manifest entry (size, sha256) before it is copied. A config that names tables of ``src``
    itself (``inputs_from == "."``) is rewritten to name ``src``'s folder.
    """
    m_src = load_manifest_for_write(src)
    info = m_src["tables"].get(table)
    old = (load_manifest_for_write(dst)["tables"].get(table) or {}).get("shards", [])
    entries = []
    for shard in (info or {}).get("shards", []):
        src_path = entry_path(src, shard["path"])
        verify_shard(src_path, shard)
        _copy_file(src_path, entry_path(dst, shard["path"]))
        entries.append(dict(shard))
    m_dst = load_manifest_for_write(dst)
    if info:
        m_dst["tables"][table] = {"rows": sum(e["rows"] for e in entries), "shards": entries}
        if table in m_src.get("configs", {}):
            config = json.loads(json.dumps(m_src["configs"][table]))
            fp = config.get("fingerprint") or {}
            if fp.get("inputs_from") == ".":
                fp["inputs_from"] = str(src.resolve())
            m_dst["configs"][table] = config
    else:
        m_dst["tables"].pop(table, None)
        m_dst["configs"].pop(table, None)
    save_manifest(dst, m_dst)
    kept = {e["path"] for e in entries}
    for s in old:
        if s["path"] not in kept:
            try:
                stale = entry_path(dst, s["path"])
            except DatasetError:
                continue
            if stale.is_file():
                stale.unlink()
