"""The skeleton of every datagen stage: a :class:`Stage` declares its params dataclass (whose
fields are the command's options and the pipeline file's keys, :mod:`mimicbench.runtime.options`),
the tables it reads and writes, its items (:class:`StagePlan`, with what it reuses) and its
per-item function; :func:`drive` owns the loop: the :class:`StageRun` (config, fingerprint reuse,
refusal of a foreign dataset, marks, status rows and copied tables; resume: FORMAT.md, "Stages and
resume"), ``begin()`` before any write, the engine (:func:`run_stage`: a failure fails only its
item), ``finish()`` with validation, and the :class:`~mimicbench.runtime.summary.StageSummary`.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from tqdm.auto import tqdm

from mimicbench.datagen.stage_options import (engine_option, jobs_option, not_a_param, omitted_unless_set,  # noqa: F401
                                              quiet_option, ray_address_option)
from mimicbench.engines import Engine, LocalEngine, Outcome, TaskResources, get_engine
from mimicbench.runtime.options import config_values
from mimicbench.runtime.summary import StageSummary
from mimicbench.schemas.errors import DatasetError, UserError
from mimicbench.schemas.folder_lock import hold
from mimicbench.schemas.fingerprint import fingerprint_mismatch, stage_config, stale_inputs, tables_fingerprint
from mimicbench.schemas.integrity import entry_path, verify_shard
from mimicbench.schemas.manifest import (MANIFEST, chmod_like_open, fsync_file, load_manifest_for_write, mark_complete,
                              mark_incomplete, save_manifest)
from mimicbench.schemas.shard_stream import ShardStream
from mimicbench.schemas.shards import _unlink_stale, has_table, read_records, remove_split, write_records
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.tables import rows_per_shard
from mimicbench.schemas.validate import validate_dataset


def run_stage(items: Sequence[Any], fn: Callable[[Any], Any], stage: str, name_of: Callable[[Any], str] = str,
              jobs: int = 1, progress: bool = True, on_done: Callable[[int, bool, Any], None] | None = None,
              engine: Engine | None = None, chunk: int = 1, resources: TaskResources = TaskResources(),
              ordered: bool = False, keep_results: bool = True) -> tuple[list[Any], list[StatusRecord]]:
    """Apply ``fn`` (picklable for a process pool or Ray) to each item on ``engine`` (default
    ``LocalEngine(jobs)``; ``jobs`` 1 runs here), ``chunk`` items a task asking for ``resources``;
    return (results in item order, unless not ``keep_results``; a status record per item named
    ``name_of(item)``). ``on_done(index, ok, result)`` is called here as each item finishes (result
    None when it failed), in completion order or, with ``ordered``, in item order (the same bytes
    on every engine for a stage that writes as it goes)."""
    if jobs < 1:
        raise ValueError(f"jobs: expected >= 1, got {jobs}")
    engine = engine or LocalEngine(jobs)
    outcomes: list[tuple[bool, str, float] | None] = [None] * len(items)
    kept: dict[int, Any] = {}
    waiting: dict[int, Outcome] = {}
    next_in_order = 0
    bar = tqdm(total=len(items), desc=stage, unit="item", disable=not progress)
    deliver = (lambda i, outcome: on_done(i, outcome.ok, outcome.result)) if on_done else (lambda i, outcome: None)
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
    return "\n".join([f"  FAILED {s.asset} [{s.stage}]: {s.reason}" for s in failed]
                     + [f"{len(statuses) - len(failed)} ok, {len(failed)} failed"])


NO_ROWS = "OUT holds no earlier rows"  # StageRun.previous's reason when there is nothing to reuse


@dataclass(frozen=True)
class Stage:
    """What a datagen stage declares: ``params`` (a dataclass type), the ``inputs`` tables read from
    IN (those IN lacks are left out), the per-item function ``item``, the ``outputs`` tables, the
    tables it ``copies`` untouched from IN (:func:`copy_table`) and the table whose config names
    the stage that made OUT (``made_by``)."""

    name: str
    params: type
    inputs: tuple[str, ...]
    item: Callable
    outputs: tuple[str, ...]
    copies: tuple[str, ...] = ()
    made_by: str = "characters"
    out_name: str = "OUT_DATASET"  # how the CLI names the output folder, for messages
    generator: str | None = None  # the config's ``generator`` of datasets made before configs named their stage
    title: str = ""  # how messages name the stage ("the zoo"; default its name)
    plan: Callable | None = None  # ``plan(run) -> StagePlan``: reads IN and OUT, decides the items; writes nothing
    out_key: str = "out"  # the params field naming the output folder
    in_key: str | None = None  # the params field naming the input folder (None: no input dataset)
    constants: tuple[tuple[str, Any], ...] = ()  # config entries that are not options (the code's version)
    check: Callable | None = None  # ``check(params)``: ValueError/UserError before anything is opened
    info: Callable | None = None  # ``info(params) -> dict``: config fields kept for the reader, not fingerprinted
    refuse_foreign: bool = True  # False: a stage that adds tables to its own input folder
    what: str = "item"  # how messages name an item ("character")
    command: tuple[str, ...] = ()  # the `mimicbench` words of its command (``("datagen", "resample")``)
    function: str = ""  # ``"module:attr"``: the command's function, params -> StageSummary (it prints the report)
    versions: tuple[str, ...] = ()  # ``"module:NAME"`` version constants of the code that makes the output
    step_reads: tuple | None = None  # for a pipeline: ``((params field, tables or None), ...)``; default IN's inputs
    step_writes: tuple[str, ...] | None = None  # the tables of OUT the stage makes (default outputs less status)
    config: Callable | None = None  # ``config(params) -> dict``: the config's entries, when not the params' own fields


class StagePlan:
    """What a stage's ``plan(run)`` decides before anything is written: the items to run and how.

    Subclasses override what differs; the defaults run ``stage.item(item, **kwargs)`` over
    :attr:`items` in one batch. Attributes:
        items: the items of this run (those not reused).
        kwargs: keyword arguments bound to the per-item function (picklable).
        reused: status rows of the work reused from OUT (``skipped``).
        statuses: status rows decided while planning (an input refused before it ran).
        drop: ``(table, split)`` of OUT removed right after ``begin()`` (rows that cannot be reused).
        resources, chunk, ordered: as :func:`run_stage` takes them.
        configs: tables given the run's config by ``finish()``.
        status_config: the config the status table gets (``"run"`` or None, as :meth:`StageRun.write`).
    """

    kwargs: dict = {}
    unchanged: bool = False  # True: the run would change nothing; the driver writes nothing (``details`` says why)
    details: dict = {}
    resources: TaskResources = TaskResources()
    chunk: int = 1
    ordered: bool = False
    configs: tuple[str, ...] = ()
    status_config: dict | None | str = "run"

    def __init__(self, stage: Stage, items: Sequence = ()):
        self.stage, self.items = stage, list(items)
        self.reused: list[StatusRecord] = []
        self.statuses: list[StatusRecord] = []
        self.drop: list[tuple[str, str]] = []
        self.reported: list[StatusRecord] | None = None  # set by :meth:`write`: the summary's rows, if not the items'

    def start(self, run: StageRun) -> None:
        """Called right after ``begin()``, before any item runs: drops :attr:`drop`."""
        for table, split in self.drop:
            run.drop_split(table, split)

    def function(self) -> Callable:
        """The per-item function the engine runs (picklable)."""
        from functools import partial

        return partial(self.stage.item, **self.kwargs) if self.kwargs else self.stage.item

    def batches(self) -> Iterable[tuple[str, Sequence]]:
        """``(progress label, items)`` batches, run one after another."""
        yield self.stage.name, self.items

    def name_of(self, item) -> str:
        """The item's name in its status row (its reuse key)."""
        return str(item)

    def engine(self, engine: Engine) -> Engine:
        """The engine that runs the items (a stage may run its items on its own local workers)."""
        return engine

    def done(self, run: StageRun, item, ok: bool, result) -> None:
        """Called here as each item finishes (after ``begin()``: it may write)."""

    def batch_done(self, run: StageRun, statuses: list[StatusRecord]) -> None:
        """Called after each batch with this run's status rows so far (a stage that writes as it goes)."""

    def nothing_made(self, statuses: list[StatusRecord]) -> bool:
        """True when the run must be undone: it had items, every one failed, and nothing was reused."""
        return bool(statuses) and not self.reused and all(s.status == "failed" for s in statuses)

    def write(self, run: StageRun, statuses: list[StatusRecord]) -> tuple[list[StatusRecord] | None, dict]:
        """Write the output tables; return (the status rows to write, None to remove the stage's
        split of the status table; the summary's details)."""
        return statuses + self.reused, {}

    def after(self, run: StageRun) -> None:
        """Work after ``finish()`` on the complete dataset (exports)."""

    def abort(self, run: StageRun, exc: BaseException | None) -> None:
        """Called (perhaps twice) when the run stops between ``begin()`` and the tables written:
        with ``exc``, or None before every item failed. Drops what :meth:`start` opened; the work
        already written stays for a re-run to resume."""

    @property
    def what(self) -> str:
        """How the message of a run whose every item failed names an item."""
        return self.stage.what

    def counts(self, statuses: list[StatusRecord]) -> tuple[int, int]:
        """(items done or reused, items failed) of this run."""
        return (sum(s.status == "ok" for s in statuses) + len(self.reused),
                sum(s.status == "failed" for s in statuses))


def engine_of(params, default_jobs: int = 1) -> Engine:
    """The engine the params' ``engine``, ``ray_address`` and ``jobs`` fields (when present) ask for."""
    return get_engine(getattr(params, "engine", "local"), getattr(params, "jobs", default_jobs) or 1,
                      getattr(params, "ray_address", None))


def drive(stage: Stage, params, engine: Engine | None = None, progress: bool | None = None) -> StageSummary:
    """Run ``stage`` with ``params``: check, plan (reads only), ``begin()``, the items on ``engine``
    (default :func:`engine_of` the params; a failure becomes a status row and the rest goes on),
    the tables and status rows, the copied inputs, ``finish()`` (validation), the plan's ``after``.

    Returns:
        The run's summary: items done (and reused), failed, seconds, the output folder, the
        status rows of this run (``statuses``) and the stage's own figures (``details``).

    Raises:
        DatasetError: every item failed and nothing was reused (OUT is then left as it was).
    """
    start = time.perf_counter()
    progress = not getattr(params, "quiet", False) if progress is None else progress
    if stage.check is not None:
        stage.check(params)
    in_dir = getattr(params, stage.in_key) if stage.in_key else None
    run = StageRun(stage, params, getattr(params, stage.out_key), in_dir,
                   info=stage.info(params) if stage.info else None, refuse_foreign=stage.refuse_foreign)
    plan = stage.plan(run)
    if plan.unchanged:  # nothing to write: OUT is left as it is
        run.lock.release()
        return StageSummary(*plan.counts([]), time.perf_counter() - start, str(run.out_dir), details=plan.details)
    run.begin()
    try:
        plan.start(run)
        statuses = list(plan.statuses)
        engine = plan.engine(engine or engine_of(params))
        fn = plan.function()
        for label, batch in plan.batches():
            batch = list(batch)
            statuses += run_stage(batch, fn, label, name_of=plan.name_of, progress=progress,
                                  on_done=lambda i, ok, result, batch=batch: plan.done(run, batch[i], ok, result),
                                  engine=engine, chunk=plan.chunk, resources=plan.resources, ordered=plan.ordered,
                                  keep_results=False)[1]
            plan.batch_done(run, statuses)
        if plan.nothing_made(statuses):
            plan.abort(run, None)
            raise run.abandon([s for s in statuses if s.status == "failed"], plan.what)
        rows, details = plan.write(run, statuses)
    except BaseException as exc:
        plan.abort(run, exc)
        raise
    if rows is None:  # no row to keep: an earlier run's go
        remove_split(run.out_dir, "status", stage.name)
    else:
        run.write_status(rows, plan.status_config)
    run.copy_inputs()
    run.finish(plan.configs)
    plan.after(run)
    ok, failed = plan.counts(statuses)
    reported = statuses if plan.reported is None else plan.reported
    if progress:
        print(summarize_statuses([s for s in reported if s.status != "skipped"]))
    return StageSummary(ok, failed, time.perf_counter() - start, str(run.out_dir), skipped=len(plan.reused),
                        statuses=tuple(reported), details=details)


class StageRun:
    """One run of ``stage`` with ``params`` from ``in_dir`` (None: no input; ``out_dir`` with
    ``refuse_foreign=False``: a stage adding tables to its input) into ``out_dir``; refuses at once
    folders inside one another and an ``out_dir`` holding another stage's dataset. It holds the
    writer's lock of ``out_dir`` (:mod:`mimicbench.schemas.folder_lock`) from its start until :meth:`finish` or
    :meth:`abandon`: a second writer of the same folder waits for it."""

    def __init__(self, stage: Stage, params, out_dir, in_dir=None, info: dict | None = None,
                 refuse_foreign: bool = True):
        self.stage, self.params, self.out_dir, self.before, self.begun = stage, params, Path(out_dir), None, False
        self.lock = hold(self.out_dir)  # one writer at a time; released by finish/abandon (or when the run is dropped)
        self.in_dir = None if in_dir is None else Path(in_dir)
        a, b = (self.in_dir or self.out_dir).resolve(), self.out_dir.resolve()
        if refuse_foreign and self.in_dir is not None and (a.is_relative_to(b) or b.is_relative_to(a)):
            raise UserError(f"{stage.name}: {stage.out_name} {out_dir} and the input {in_dir} must be separate "
                            f"folders, neither inside the other")
        pending = ((self.manifest() or {}).get("pending") or {}).get("stage") if a == b else None
        self.resuming = pending == stage.name  # a stage writing its input folder, resuming its killed run there
        inputs = [t for t in stage.inputs if self.in_dir is not None
                  and has_table(self.in_dir, t, allow_incomplete=self.resuming)]
        values = {**dict(stage.constants), **(stage.config(params) if stage.config else config_values(params))}
        self.config = stage_config({"stage": stage.name, **{k: v.to_json() if hasattr(v, "to_json") else v
                                                            for k, v in values.items()}},
                                   tables_fingerprint(self.in_dir, inputs) if inputs else {},
                                   "." if a == b else str(a), info)
        if refuse_foreign:
            self.refuse_foreign()

    def manifest(self) -> dict | None:
        """OUT's manifest, or None when OUT holds no dataset yet."""
        return load_manifest_for_write(self.out_dir) if (self.out_dir / MANIFEST).exists() else None

    def refuse_foreign(self) -> None:
        """DatasetError when OUT holds tables whose ``made_by`` config names another stage (and no
        run of this stage is pending there)."""
        manifest = self.manifest()
        if manifest is None or not manifest["tables"]:
            return
        made = manifest["configs"].get(self.stage.made_by) or {}
        if self.stage.name not in (made.get("stage"), (manifest.get("pending") or {}).get("stage")) \
                and (self.stage.generator is None or made.get("generator") != self.stage.generator):
            by = made.get("stage") or made.get("generator") or "another stage"
            raise DatasetError(f"{self.out_dir}: holds a dataset made by {by}, not by {self.stage.title or self.stage.name}"
                               f"; choose an empty or new {self.stage.out_name} (nothing was changed)")

    def previous(self, pending: bool = True) -> tuple[dict | None, str | None]:
        """(the config OUT's rows were made under, why they cannot be reused: None when they can):
        that of an unfinished run of this stage when ``pending``, else of OUT's ``made_by`` table."""
        manifest = self.manifest()
        if manifest is None or not manifest["tables"].get(self.stage.made_by):
            return None, NO_ROWS
        run = manifest.get("pending") or {}
        old = run.get("config") if pending and run.get("stage") == self.stage.name \
            else manifest["configs"].get(self.stage.made_by)
        return old, fingerprint_mismatch(old, self.config)

    def earlier_rows(self, table: str, split: str | None = None, drop=()) -> list:
        """The rows earlier runs put in OUT's ``table`` (one split or all), less those of ``drop``'s character IDs."""
        if self.manifest() is None or not has_table(self.out_dir, table, split, allow_incomplete=True):
            return []
        return [r for r in read_records(self.out_dir, table, split, allow_incomplete=True)
                if getattr(r, "character_id", None) not in drop]

    def begin(self) -> None:
        """Mark OUT incomplete (``pending``: this stage and its config) until :meth:`finish`."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.before, self.begun = self.manifest(), True
        mark_incomplete(self.out_dir, self.stage.name, self.config)

    def drop_split(self, table: str, split: str) -> None:
        """Remove one split of OUT's ``table`` (rows that cannot be reused), also from the manifest
        :meth:`abandon` would restore."""
        remove_split(self.out_dir, table, split)
        info = ((self.before or {}).get("tables") or {}).get(table)
        if info:
            info["shards"] = [e for e in info["shards"] if e["split"] != split]
            info["rows"] = sum(e["rows"] for e in info["shards"])
            if not info["shards"]:
                del self.before["tables"][table]

    def abandon(self, statuses: list[StatusRecord], what: str) -> DatasetError:
        """Undo :meth:`begin` if it ran (the old manifest, or no folder) after a run in which every
        item failed; return the error to raise, naming the first reasons."""
        if self.begun and self.before is not None:
            save_manifest(self.out_dir, self.before)
        elif self.begun:
            (self.out_dir / MANIFEST).unlink(missing_ok=True)
            for folder in [self.out_dir / t for t in self.stage.outputs] + [self.out_dir]:
                if folder.is_dir() and not any(folder.iterdir()):
                    folder.rmdir()
        self.lock.release()
        reasons = "; ".join(f"{s.asset}: {s.reason}" for s in statuses[:3]) + ("; ..." if len(statuses) > 3 else "")
        return DatasetError(f"{self.stage.name}: every {what} failed ({reasons}); {self.out_dir} left as it was"
                            + ("" if self.before is not None else " (nothing written)"))

    def write(self, table: str, records, split: str, config: dict | None | str = "run") -> list[dict]:
        """Write one split of ``table``, return its entries; ``config`` for the table: ``"run"`` the
        run's, None leaves the manifest's (part shards' table gets it in :meth:`finish`)."""
        return write_records(self.out_dir, table, list(records), split, rows_per_shard(table, self.stage.name),
                             config=self.config if config == "run" else config)

    @contextmanager
    def streams(self, keys: Iterable[tuple[str, str]], config: dict | None | str = "run"):
        """``{(table, split): ShardStream}`` (``config`` as in :meth:`write`): closed at the end, aborted on an error."""
        streams = self.open_streams(keys, config)
        try:
            yield streams
        except BaseException:
            for stream in streams.values():
                stream.abort()
            raise
        for stream in streams.values():
            stream.close()

    def open_streams(self, keys: Iterable[tuple[str, str]], config: dict | None | str = "run") -> dict:
        """``{(table, split): ShardStream}`` (``config`` as in :meth:`write`); the caller closes or aborts each."""
        return {(t, s): ShardStream(self.out_dir, t, s, rows_per_shard(t, self.stage.name),
                                    self.config if config == "run" else config) for t, s in keys}

    def write_splits(self, table: str, records, splits=()) -> None:
        """Write ``records`` of ``table`` a split at a time, in sorted order; a split of ``splits``
        that none of them is in gets an empty shard (it replaces what an earlier run wrote there)."""
        records = list(records)
        for split in sorted(set(splits) | {r.split for r in records}):
            self.write(table, [r for r in records if r.split == split], split)

    def copy_inputs(self) -> None:
        """Copy the tables the stage ``copies`` from IN, untouched (:func:`copy_table`)."""
        for table in self.stage.copies:
            copy_table(self.in_dir, self.out_dir, table)

    def write_status(self, rows: list[StatusRecord], config: dict | None | str = "run") -> None:
        """The stage's status rows: split ``stage.name`` of the ``status`` table."""
        self.write("status", rows, self.stage.name, config)

    def finish(self, configs: Iterable[str] = ()) -> None:
        """Give the ``configs`` tables the run's config, mark OUT complete, validate it. A table of
        another stage that this run made stale (``cases`` of a zoo rebuilt in place) is a warning
        on stderr naming the command to re-run, not a failure of this stage."""
        manifest = load_manifest_for_write(self.out_dir)
        manifest["configs"].update({t: self.config for t in configs})
        save_manifest(self.out_dir, manifest)
        mark_complete(self.out_dir)
        manifest = load_manifest_for_write(self.out_dir)
        stale = {stale_inputs(self.out_dir, manifest, t) for t in manifest["tables"] if t not in self.stage.outputs}
        stale.discard(None)
        for message in sorted(stale):
            print(f"warning: {message}", file=sys.stderr)
        problems = [p for p in validate_dataset(self.out_dir) if p not in stale]
        self.lock.release()
        if problems:
            raise RuntimeError(f"{self.stage.name} wrote an invalid dataset:\n" + "\n".join(problems))


def copy_table(src: Path, dst: Path, table: str) -> None:
    """Make ``dst``'s ``table`` a copy of ``src``'s (or drop it when ``src`` has none): paths confined
    to their folders, each shard verified against ``src``'s manifest (size, sha256), then copied
    through a fsynced temporary file; a config naming ``src``'s own tables (``inputs_from == "."``)
    is rewritten to name ``src``'s folder."""
    m_src = load_manifest_for_write(src)
    info = m_src["tables"].get(table)
    old = (load_manifest_for_write(dst)["tables"].get(table) or {}).get("shards", [])
    for shard in (info or {}).get("shards", []):
        verify_shard(entry_path(src, shard["path"]), shard)
        final = entry_path(dst, shard["path"])
        final.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent)
        os.close(fd)
        try:
            shutil.copyfile(entry_path(src, shard["path"]), tmp)
            fsync_file(tmp)
            chmod_like_open(tmp)
            os.replace(tmp, final)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    m_dst = load_manifest_for_write(dst)
    if info:
        m_dst["tables"][table] = {"rows": sum(s["rows"] for s in info["shards"]),
                                  "shards": [dict(s) for s in info["shards"]]}
        config = m_src.get("configs", {}).get(table)
        if config is not None:
            config = json.loads(json.dumps(config))
            if (config.get("fingerprint") or {}).get("inputs_from") == ".":
                config["fingerprint"]["inputs_from"] = str(src.resolve())
            m_dst["configs"][table] = config
    else:
        m_dst["tables"].pop(table, None)
        m_dst["configs"].pop(table, None)
    save_manifest(dst, m_dst)
    kept = {s["path"] for s in (info or {}).get("shards", [])}
    _unlink_stale(dst, [s for s in old if s["path"] not in kept])
