"""The resample stage over a dataset: ``mimicbench datagen resample IN OUT`` (resume: FORMAT.md,
"Stages and resume"). Input characters are read a row group at a time and resampled ``BATCH`` at a
time; finished ones go to part splits ``part_00000``... as they come, streamed into the final shards.
"""
from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from datagen.resample.character import resample_character
from datagen.resample import MAX_FACES, MIN_FACES, RESAMPLE_VERSION
from mimicbench.engines import Engine, TaskResources
from mimicbench.validation import expect, is_whole
from datagen.stage_runner import Stage, StageRun, run_stage, summarize_statuses
from schemas.errors import DatasetError
from schemas.fingerprint import fingerprint_mismatch
from schemas.shard_stream import checked_parquet_file, iter_records, iter_row_groups, read_row_group
from schemas.rigid_body import PHYSICS_TABLES
from schemas.shards import readable_entries, remove_split, splits_of
from schemas.status import StatusRecord
from schemas.tables import ROW_GROUP_SIZE, rows_per_shard

BACKENDS = ("fast", "pymeshlab")
PART = "part_"  # split-name prefix of the shards written while the stage runs
TASK_RESOURCES = TaskResources(num_cpus=1, memory=2 << 30)  # one character: mesh, KD-tree, weights
BATCH = 64  # input characters in memory (and handed to the engine) at a time


@dataclass(frozen=True)
class ResampleParams:
    """version: the stage's code version (:data:`RESAMPLE_VERSION`); faces: target face count;
    backend: one of :data:`BACKENDS`."""

    version: str = RESAMPLE_VERSION
    faces: int = 5000
    backend: str = "fast"


def _one(item, faces, backend):
    record, motions = item
    return resample_character(record, motions, faces, backend)


STAGE = Stage("resample", ResampleParams, inputs=("characters", "motions"), item=_one,
              outputs=("characters", "status"), copies=("motions", "pairs", *PHYSICS_TABLES))


def _reusable_rows(run: StageRun) -> tuple[dict, list[str]]:
    """Where the rows of OUT made with the same fingerprints as ``run.config`` are
    (``{character_id: (manifest entry, row group)}``), and notes on the rows that cannot be reused
    and why. Drops part shards of an interrupted run with other fingerprints."""
    manifest, done, notes = run.manifest() or {"tables": {}}, {}, []
    shards = manifest["tables"].get("characters", {}).get("shards", [])
    for parts in (False, True):  # a finished run's splits (its config), then an interrupted run's (pending)
        splits = sorted({s["split"] for s in shards if s["split"].startswith(PART) == parts})
        why = None if not splits else run.previous(pending=False)[1] if not parts else \
            fingerprint_mismatch((manifest.get("pending") or {}).get("config"), run.config)
        for split in splits:
            if why is None:
                done.update(_rows_or_note(run.out_dir, split, notes))
            elif parts:
                remove_split(run.out_dir, "characters", split)
        if why is not None:
            notes.append(f"dropped the parts of an interrupted run that does not match ({why})" if parts else
                         f"{run.out_dir} holds a run that does not match ({why}): every character is redone (the "
                         f"old rows are replaced once this run has produced some)")
    return done, notes


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


def resample_dataset(in_dir, out_dir, faces: int = 5000, backend: str = "fast", jobs: int = 1,
                     progress: bool = True, flush_every: int = 8, flush_seconds: float = 60.0,
                     engine: Engine | None = None) -> dict:
    """Resample every character of ``in_dir`` into ``out_dir``, writing finished work as it goes.

    Characters that fail get a status row (split ``resample``) with the reason and are left out;
    skeleton-only characters (no mesh) are copied as they are. The motions table (and pairs, if
    any) are copied unchanged (verified against the input's manifest).

    Args:
        flush_every, flush_seconds: write finished characters after this many, or this long.
        engine: where characters are resampled (:mod:`mimicbench.engines`; default the local engine
            with ``jobs`` processes); one character a task of 1 CPU and 2 GiB.

    Returns:
        Summary: counts, failures, mean Hausdorff and transfer error (% of height), seconds,
        ``notes`` (why earlier rows in ``out_dir`` were not reused).

    Raises:
        ValueError: a bad argument.
        DatasetError: ``in_dir`` is not a dataset or has no characters; ``out_dir`` holds another
            stage's dataset; every character failed (``out_dir`` is then left as it was).
    """
    start = time.perf_counter()
    in_dir, out_dir = Path(in_dir), Path(out_dir)
    expect(is_whole(faces) and MIN_FACES <= faces <= MAX_FACES, "faces", f"an integer from {MIN_FACES} to {MAX_FACES}",
           faces)
    expect(backend in BACKENDS, "backend", f"one of {BACKENDS}", backend)
    expect(jobs >= 1 and flush_every >= 1, "jobs, flush_every", ">= 1", (jobs, flush_every))
    order, meshless = [], {}  # (character ID, split) in input order; skeleton-only records (copied as they are)
    for _, _, group in iter_row_groups(in_dir, "characters"):  # DatasetError when IN is not a dataset
        for r in group:
            order.append((r.character_id, r.split, len(r.faces) > 0))
            if len(r.faces) == 0:
                meshless[r.character_id] = r
    if not order:
        raise DatasetError(f"{in_dir}: the characters table has no rows; nothing to resample")
    run = StageRun(STAGE, ResampleParams(faces=int(faces), backend=backend), out_dir, in_dir, info={"source": str(in_dir)})
    # a damaged motions shard stops the stage here, before OUT is touched
    frames = _sampled_motions(in_dir) if "motions" in run.config["fingerprint"]["inputs"] else {}
    done, notes = _reusable_rows(run)
    run.begin()

    where = dict(done)  # character ID -> (shard entry, row group) of its resampled row
    parts = [s for s in splits_of(out_dir, "characters", allow_incomplete=True) if s.startswith(PART)]
    next_part = [max((int(p[len(PART):]) for p in parts), default=-1) + 1]
    buffer: list = []
    last_flush = [time.monotonic()]
    group_rows, shard_rows = ROW_GROUP_SIZE["characters"], rows_per_shard("characters", STAGE.name)

    def flush() -> None:
        if buffer:
            entries = run.write("characters", buffer, f"{PART}{next_part[0]:05d}", config=None)
            for k, r in enumerate(buffer):
                where[r.character_id] = (entries[k // shard_rows], (k % shard_rows) // group_rows)
            next_part[0] += 1
            buffer.clear()
        last_flush[0] = time.monotonic()

    def on_done(i, ok, result) -> None:
        if ok:
            buffer.append(result)
        if len(buffer) >= flush_every or time.monotonic() - last_flush[0] >= flush_seconds:
            flush()

    statuses: list[StatusRecord] = []
    todo = sum(has_mesh and cid not in done for cid, _, has_mesh in order)
    fn = partial(STAGE.item, faces=run.params.faces, backend=run.params.backend)
    for n, batch in enumerate(_batches(in_dir, done), 1):
        label = "resample" if todo <= len(batch) else f"resample {min(n * BATCH, todo)}/{todo}"
        statuses += run_stage([(r, frames.get(r.character_id, [])) for r in batch], fn, label,
                              name_of=lambda item: item[0].character_id, jobs=jobs, progress=progress, on_done=on_done,
                              engine=engine, resources=TASK_RESOURCES, keep_results=False)[1]
    flush()
    if any(has_mesh for *_, has_mesh in order) and not any(has_mesh and cid in where for cid, _, has_mesh in order):
        raise run.abandon(statuses, "character")  # every meshed character failed

    read, quality, count = _row_reader(out_dir), [], 0
    splits = splits_of(in_dir, "characters")
    with run.streams([("characters", split) for split in splits], config=None) as streams:
        for cid, split, has_mesh in order:
            if not has_mesh:
                row = meshless[cid]
            elif cid in where:
                row = read(cid, where[cid])
            else:
                continue  # failed: its status row says why
            streams["characters", split].add([row])
            count += 1
            if (row.meta or {}).get("resample"):
                quality.append((row.meta["resample"]["hausdorff_pct"], row.meta["resample"]["transfer_error_pct"]))
    wanted = set(splits)
    for split in splits_of(out_dir, "characters", allow_incomplete=True):
        if split not in wanted:  # parts, and splits of an earlier run the input no longer has
            remove_split(out_dir, "characters", split)
    skipped = [StatusRecord(cid, "resample", "skipped", "already resampled", 0.0) for cid in done]
    run.write_status(statuses + skipped)
    run.copy_inputs()
    run.finish(configs=["characters"])
    q = np.asarray(quality, dtype=np.float64).reshape(-1, 2)
    if progress:
        print(summarize_statuses(statuses))
    return {"characters": count, "resampled": sum(s.status == "ok" for s in statuses), "already_done": len(done),
            "failed": sum(s.status == "failed" for s in statuses),
            "hausdorff_pct_mean": float(np.mean(q[:, 0])) if len(q) else None,
            "transfer_error_pct_mean": float(np.mean(q[:, 1])) if len(q) else None,
            "seconds": time.perf_counter() - start, "statuses": statuses, "notes": notes}
