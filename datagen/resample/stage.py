"""The resample stage over a dataset: ``mimicbench datagen resample IN OUT`` (resume: FORMAT.md,
"Stages and resume"). Input characters are read a row group at a time and resampled ``BATCH`` at a
time; finished ones go to part splits ``part_00000``... as they come, streamed into the final shards.
"""
from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path

import numpy as np

from mimicbench.datagen.resample.character import resample_character
from mimicbench.datagen.resample import MAX_FACES, MIN_FACES, RESAMPLE_VERSION
from mimicbench.engines import Engine, TaskResources
from mimicbench.geometry.validation import expect, is_whole
from mimicbench.datagen.resample.params import BACKENDS, ResampleParams
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.fingerprint import fingerprint_mismatch
from mimicbench.schemas.shard_stream import checked_parquet_file, iter_records, iter_row_groups, read_row_group
from mimicbench.schemas.rigid_body import PHYSICS_TABLES
from mimicbench.schemas.shards import readable_entries, remove_split, splits_of
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.tables import ROW_GROUP_SIZE, rows_per_shard

PART = "part_"  # split-name prefix of the shards written while the stage runs
TASK_RESOURCES = TaskResources(num_cpus=1, memory=2 << 30)  # one character: mesh, KD-tree, weights
BATCH = 64  # input characters in memory (and handed to the engine) at a time


def _one(item, faces, backend):
    record, motions = item
    return resample_character(record, motions, faces, backend)


def _check(params: ResampleParams) -> None:
    expect(is_whole(params.faces) and MIN_FACES <= params.faces <= MAX_FACES, "faces",
           f"an integer from {MIN_FACES} to {MAX_FACES}", params.faces)
    expect(params.backend in BACKENDS, "backend", f"one of {BACKENDS}", params.backend)
    expect(params.jobs >= 1, "jobs", ">= 1", params.jobs)


STAGE = Stage("resample", ResampleParams, inputs=("characters", "motions"), item=_one,
              outputs=("characters", "status"), copies=("motions", "pairs", *PHYSICS_TABLES),
              plan=lambda run: ResamplePlan(run), out_key="out_dataset", in_key="in_dataset",
              constants=(("version", RESAMPLE_VERSION),), check=_check,
              info=lambda params: {"source": str(params.in_dataset)}, what="character",
              command=("datagen", "resample"), function="mimicbench.datagen.resample.stage:run_command",
              versions=("mimicbench.datagen.resample:RESAMPLE_VERSION",), step_writes=("characters", "motions"))


def _reusable_rows(run: StageRun) -> tuple[dict, list[str], list[tuple[str, str]]]:
    """Where the rows of OUT made with the same fingerprints as ``run.config`` are
    (``{character_id: (manifest entry, row group)}``), notes on the rows that cannot be reused
    and why, and the part splits of an interrupted run with other fingerprints (to drop)."""
    manifest, done, notes, drop = run.manifest() or {"tables": {}}, {}, [], []
    shards = manifest["tables"].get("characters", {}).get("shards", [])
    for parts in (False, True):  # a finished run's splits (its config), then an interrupted run's (pending)
        splits = sorted({s["split"] for s in shards if s["split"].startswith(PART) == parts})
        why = None if not splits else run.previous(pending=False)[1] if not parts else \
            fingerprint_mismatch((manifest.get("pending") or {}).get("config"), run.config)
        for split in splits:
            if why is None:
                done.update(_rows_or_note(run.out_dir, split, notes))
            elif parts:
                drop.append(("characters", split))
        if why is not None:
            notes.append(f"dropped the parts of an interrupted run that does not match ({why})" if parts else
                         f"{run.out_dir} holds a run that does not match ({why}): every character is redone (the "
                         f"old rows are replaced once this run has produced some)")
    return done, notes, drop


def _rows_or_note(out_dir: Path, split: str, notes: list[str]) -> dict:
    """``{character_id: (manifest entry, row group)}`` of one split of ``out_dir`` (only the IDs are
    read, after each shard's checks); a split that fails its checks (e.g. a shard replaced by a run
    killed before it updated the manifest) is redone, with a note."""
    try:
        where = {}
        for e in readable_entries(out_dir, "characters", split, allow_incomplete=True):
            pf = checked_parquet_file(out_dir, e, "characters")
            for g in range(pf.num_row_groups):
                ids = pf.read_row_group(g, columns=["character_id"]).column(0).to_pylist()
                where.update((cid, (e, g)) for cid in ids)
        return where
    except DatasetError as exc:
        notes.append(f"the rows of split {split!r} cannot be reused and are redone ({exc})")
        return {}


def _row_reader(out_dir: Path, keep: int = 4):
    """``read(cid, (manifest entry, row group))``: that record of OUT's characters (the last ``keep``
    row groups read are kept)."""
    entries: dict[str, dict] = {}

    @functools.lru_cache(maxsize=keep)
    def group(path: str, g: int) -> dict:
        return {r.character_id: r for r in read_row_group(checked_parquet_file(out_dir, entries[path], "characters"),
                                                          g, "characters")}

    def read(cid: str, where: tuple):
        entries[where[0]["path"]] = where[0]
        return group(where[0]["path"], where[1])[cid]
    return read


def _sampled_motions(in_dir: Path) -> dict[str, list]:
    """``{character_id: [motion cut to its 3 measured frames]}`` (:func:`_sampled`): 3 (K, 7) frames a clip."""
    out: dict[str, list] = {}
    for m in iter_records(in_dir, "motions"):  # one shard in memory
        out.setdefault(m.character_id, []).append(_sampled(m))
    return out


def _batches(in_dir: Path, done: dict):
    """The meshed characters of ``in_dir`` not in ``done``, :data:`BATCH` or more at a time (a row group read at a time)."""
    batch = []
    for _, _, group in iter_row_groups(in_dir, "characters"):
        batch += [r for r in group if len(r.faces) > 0 and r.character_id not in done]
        if len(batch) >= BATCH:
            yield batch
            batch = []
    if batch:
        yield batch


def _sampled(m):
    """A motion cut to the 3 frames :func:`sample_frames` takes of each clip (first, middle, last)."""
    idx = np.linspace(0, m.num_frames - 1, 3).astype(int)
    return dataclasses.replace(m, transforms=np.ascontiguousarray(m.transforms[idx]), num_frames=3,
                               scale=None if m.scale is None else np.ascontiguousarray(m.scale[idx]))


class ResamplePlan(StagePlan):
    """The characters of IN not reusable from OUT, :data:`BATCH` at a time (a row group read at a
    time); finished ones go to part splits as they come (:meth:`done`), then :meth:`write` streams
    every row into the final shards in input order."""

    resources = TASK_RESOURCES
    configs = ("characters",)

    def __init__(self, run: StageRun, flush_every: int = 8, flush_seconds: float = 60.0):
        super().__init__(run.stage)
        expect(flush_every >= 1, "flush_every", ">= 1", flush_every)
        self.flush_every, self.flush_seconds = flush_every, flush_seconds
        params, in_dir = run.params, run.in_dir
        self.order, self.meshless = [], {}  # (character ID, split, has a mesh) in input order; skeleton-only records
        for _, _, group in iter_row_groups(in_dir, "characters"):  # DatasetError when IN is not a dataset
            for r in group:
                self.order.append((r.character_id, r.split, len(r.faces) > 0))
                if len(r.faces) == 0:
                    self.meshless[r.character_id] = r
        if not self.order:
            raise DatasetError(f"{in_dir}: the characters table has no rows; nothing to resample")
        # a damaged motions shard stops the stage here, before OUT is touched
        self.frames = _sampled_motions(in_dir) if "motions" in run.config["fingerprint"]["inputs"] else {}
        self.reusable, self.notes, self.drop = _reusable_rows(run)
        self.reused = [StatusRecord(cid, "resample", "skipped", "already resampled", 0.0) for cid in self.reusable]
        self.kwargs = {"faces": params.faces, "backend": params.backend}
        self.run, self.in_dir, self.out_dir = run, in_dir, run.out_dir
        self.where = dict(self.reusable)  # character ID -> (shard entry, row group) of its resampled row
        self.buffer: list = []
        self.last_flush = time.monotonic()
        self.next_part = None

    def name_of(self, item) -> str:
        return item[0].character_id

    def batches(self):
        todo = sum(has_mesh and cid not in self.reusable for cid, _, has_mesh in self.order)
        for n, batch in enumerate(_batches(self.in_dir, self.reusable), 1):
            label = "resample" if todo <= len(batch) else f"resample {min(n * BATCH, todo)}/{todo}"
            yield label, [(r, self.frames.get(r.character_id, [])) for r in batch]

    def flush(self, run: StageRun) -> None:
        if self.next_part is None:
            parts = [s for s in splits_of(self.out_dir, "characters", allow_incomplete=True) if s.startswith(PART)]
            self.next_part = max((int(p[len(PART):]) for p in parts), default=-1) + 1
        if self.buffer:
            group_rows, shard_rows = ROW_GROUP_SIZE["characters"], rows_per_shard("characters", STAGE.name)
            entries = run.write("characters", self.buffer, f"{PART}{self.next_part:05d}", config=None)
            for k, r in enumerate(self.buffer):
                self.where[r.character_id] = (entries[k // shard_rows], (k % shard_rows) // group_rows)
            self.next_part += 1
            self.buffer.clear()
        self.last_flush = time.monotonic()

    def done(self, run, item, ok, result) -> None:
        if ok:
            self.buffer.append(result)
        if len(self.buffer) >= self.flush_every or time.monotonic() - self.last_flush >= self.flush_seconds:
            self.flush(run)

    def nothing_made(self, statuses) -> bool:
        self.flush(self.run)
        return any(m for *_, m in self.order) and not any(m and cid in self.where for cid, _, m in self.order)

    def write(self, run, statuses):
        read, quality, count = _row_reader(self.out_dir), [], 0
        splits = splits_of(self.in_dir, "characters")
        with run.streams([("characters", split) for split in splits], config=None) as streams:
            for cid, split, has_mesh in self.order:
                if not has_mesh:
                    row = self.meshless[cid]
                elif cid in self.where:
                    row = read(cid, self.where[cid])
                else:
                    continue  # failed: its status row says why
                streams["characters", split].add([row])
                count += 1
                if (row.meta or {}).get("resample"):
                    quality.append((row.meta["resample"]["hausdorff_pct"], row.meta["resample"]["transfer_error_pct"]))
        wanted = set(splits)
        for split in splits_of(self.out_dir, "characters", allow_incomplete=True):
            if split not in wanted:  # parts, and splits of an earlier run the input no longer has
                remove_split(self.out_dir, "characters", split)
        q = np.asarray(quality, dtype=np.float64).reshape(-1, 2)
        return statuses + self.reused, {
            "characters": count, "resampled": sum(s.status == "ok" for s in statuses),
            "already_done": len(self.reused), "notes": self.notes,
            "hausdorff_pct_mean": float(np.mean(q[:, 0])) if len(q) else None,
            "transfer_error_pct_mean": float(np.mean(q[:, 1])) if len(q) else None}


def resample_dataset(in_dir, out_dir, faces: int = 5000, backend: str = "fast", jobs: int = 1,
                     progress: bool = True, flush_every: int = 8, flush_seconds: float = 60.0,
                     engine: Engine | None = None) -> dict:
    """Resample every character of ``in_dir`` into ``out_dir`` (:func:`drive` with :data:`STAGE`),
    writing finished work as it goes.

    Characters that fail get a status row (split ``resample``) with the reason and are left out;
    skeleton-only characters (no mesh) are copied as they are. The motions table (and pairs, if
    any) are copied unchanged (verified against the input's manifest).

    Args:
        flush_every, flush_seconds: write finished characters after this many, or this long.
        engine: where characters are resampled (:mod:`mimicbench.engines`; default the local engine
            with ``jobs`` processes); one character a task of 1 CPU and 2 GiB.

    Returns:
        The summary's ``details`` with ``failed``, ``seconds`` and ``statuses``: counts, failures,
        mean Hausdorff and transfer error (% of height), ``notes`` (why earlier rows in ``out_dir``
        were not reused).

    Raises:
        ValueError: a bad argument.
        DatasetError: ``in_dir`` is not a dataset or has no characters; ``out_dir`` holds another
            stage's dataset; every character failed (``out_dir`` is then left as it was).
    """
    params = ResampleParams(str(in_dir), str(out_dir), faces=faces, backend=backend, jobs=jobs, quiet=not progress)
    stage = dataclasses.replace(STAGE, plan=lambda run: ResamplePlan(run, flush_every, flush_seconds))
    s = drive(stage, params, engine=engine)
    return {**s.details, "failed": s.failed, "seconds": s.seconds, "statuses": list(s.statuses)}


def run_command(params: ResampleParams) -> StageSummary:
    """``mimicbench datagen resample``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    s = drive(STAGE, params)
    d = s.details
    for note in d["notes"]:
        print(f"resample: {note}")
    h, t = d["hausdorff_pct_mean"], d["transfer_error_pct_mean"]
    print(f"{d['resampled']} resampled, {d['already_done']} already done, {s.failed} failed in {s.seconds:.1f} s; "
          f"mean Hausdorff {h if h is None else round(h, 3)} %, mean transfer error {t if t is None else round(t, 3)} % "
          f"of height -> {params.out_dataset}")
    return s
