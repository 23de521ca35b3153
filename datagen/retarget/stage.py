"""``datagen retarget`` as a stage: every clip of a motions dataset onto every humanoid of a
characters dataset, into a new dataset, with a status row and a report per pair."""
from __future__ import annotations

import fnmatch
import json
import time
from dataclasses import dataclass

from mimicbench.datagen.retarget.retarget import retarget_clip
from mimicbench.datagen.retarget.roles import humanoid_roles
from mimicbench.datagen.stage_runner import Stage, StageRun
from mimicbench.schemas.rigid_body import PHYSICS_TABLES
from mimicbench.schemas.shards import has_table, read_records
from mimicbench.schemas.status import StatusRecord

MIN_ROLES = 8


@dataclass(frozen=True)
class RetargetParams:
    """sources, targets: globs on the source and target character IDs."""

    sources: str = "*"
    targets: str = "*"


STAGE = Stage("retarget", RetargetParams, inputs=("characters", "motions"), item=retarget_clip,
              outputs=("characters", "motions", "status", *PHYSICS_TABLES), out_name="OUT folder")


def _write_physics(run: StageRun, characters_dir, targets: list) -> None:
    """The ``targets``' own rigid bodies and joints (an MMD file's physics) from ``characters_dir``,
    in their characters' splits (a split without any: an empty shard, replacing an earlier run's),
    so that ``datagen apparel`` simulates a retargeted clip with the file's physics; no table when
    ``characters_dir`` has none."""
    split = {t.character_id: t.split for t in targets}
    for table in PHYSICS_TABLES:
        if not has_table(characters_dir, table):
            continue
        rows = [r for r in read_records(characters_dir, table) if r.character_id in split]
        for sp in sorted(set(split.values())):
            run.write(table, [r for r in rows if split[r.character_id] == sp], sp)


def _refuse_empty(motions_dir, characters_dir, sources: tuple, targets: tuple, clips: list) -> None:
    """Refuse a run with nothing to retarget, before anything is written (an empty dataset with exit
    status 0 would look like a finished run): ``sources``/``targets`` are ``(option, glob, every
    character, the matching ones)``; ``clips`` the matching sources' clips."""
    for (option, glob, every, matched), folder in ((sources, motions_dir), (targets, characters_dir)):
        if not matched:
            ids = ", ".join(repr(c.character_id) for c in every[:3]) + (", ..." if len(every) > 3 else "")
            raise ValueError(f"{option} {glob!r} matches none of the {len(every)} characters of {folder}"
                             + (f" ({ids})" if every else "") + "; expected a glob on character IDs")
    if not clips:
        raise ValueError(f"{motions_dir}: the {len(sources[3])} character(s) matching --sources {sources[1]!r} have "
                         f"no clips; nothing to retarget")


def retarget_datasets(motions_dir, characters_dir, out_dir, sources: str = "*", targets: str = "*",
                      progress: bool = True) -> dict:
    """Retarget the clips of ``motions_dir``'s characters matching the glob ``sources`` onto those of
    ``characters_dir`` matching ``targets`` with at least :data:`MIN_ROLES` humanoid bone roles, into
    ``out_dir``: the targets (with their own rigid bodies and joints, an MMD file's physics), the
    clips (``<target>/<source>/<clip>``), a status row per pair and ``retarget_report.json``
    (mapped and unmapped bones per pair). Returns a summary."""
    from tqdm.auto import tqdm

    start = time.perf_counter()
    run = StageRun(STAGE, RetargetParams(sources, targets), out_dir, motions_dir,  # fingerprints: the clips' dataset
                   info={"motions": str(motions_dir), "characters": str(characters_dir)})
    all_sources = read_records(motions_dir, "characters")
    src_chars = {c.character_id: c for c in all_sources if fnmatch.fnmatch(c.character_id, sources)}
    clips = [m for m in read_records(motions_dir, "motions") if m.character_id in src_chars]
    all_targets = read_records(characters_dir, "characters")
    tgts = [c for c in all_targets if fnmatch.fnmatch(c.character_id, targets)]
    _refuse_empty(motions_dir, characters_dir, ("--sources", sources, all_sources, src_chars),
                  ("--targets", targets, all_targets, tgts), clips)
    statuses, reports, out_motions, used = [], [], [], {}
    humanoid = [t for t in tgts if len(humanoid_roles(t.bone_names)) >= MIN_ROLES]
    for t in tgts:
        if t not in humanoid:
            statuses.append(StatusRecord(t.character_id, "retarget", "skipped",
                                         f"fewer than {MIN_ROLES} humanoid bone roles in its names", 0.0))
    pairs = [(m, t) for m in clips for t in humanoid if t.character_id != m.character_id]
    for m, t in tqdm(pairs, desc="retarget", unit="clip", disable=not progress):
        t0 = time.perf_counter()
        asset = f"{m.motion_id} -> {t.character_id}"
        try:
            rec, report = STAGE.item(src_chars[m.character_id], m, t)
        except ValueError as e:
            statuses.append(StatusRecord(asset, "retarget", "failed", str(e), time.perf_counter() - t0))
            continue
        out_motions.append(rec)
        reports.append(report)
        used[t.character_id] = t
        statuses.append(StatusRecord(asset, "retarget", "ok", f"{len(report['mapped'])} roles mapped, "
                                     f"{len(report['target_unmapped'])} target bones at rest", time.perf_counter() - t0))
    run.begin()
    chars = list(used.values())
    run.write_splits("characters", chars)
    run.write_splits("motions", out_motions)
    run.write_status(statuses)
    _write_physics(run, characters_dir, chars)
    (run.out_dir / "retarget_report.json").write_text(json.dumps(reports, ensure_ascii=False, indent=1))
    run.finish()
    return {"pairs": len(pairs), "clips": len(out_motions), "characters": len(chars),
            "failed": sum(s.status == "failed" for s in statuses), "statuses": statuses,
            "seconds": time.perf_counter() - start}
