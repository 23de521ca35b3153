"""``datagen retarget`` as a stage: every clip of a motions dataset onto every humanoid of a
characters dataset, into a new dataset, with a status row and a report per pair."""
from __future__ import annotations

import dataclasses
import fnmatch
import json

from mimicbench.datagen.retarget.retarget import retarget_clip
from mimicbench.datagen.retarget.roles import humanoid_roles
from mimicbench.datagen.retarget.params import RetargetParams
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.schemas.rigid_body import PHYSICS_TABLES
from mimicbench.schemas.shards import has_table, read_records
from mimicbench.schemas.status import StatusRecord

MIN_ROLES = 8


def _one(item):
    """``(source character, clip, target)`` -> (motion record, report), or (None, why) when the clip
    cannot be retargeted (a ValueError: its reason goes to the status row as it is)."""
    try:
        return retarget_clip(*item)
    except ValueError as e:
        return None, str(e)


class RetargetPlan(StagePlan):
    """Every (clip, humanoid target) pair one item; targets with too few humanoid roles are skipped."""

    ordered = True

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        p = run.params
        all_sources = read_records(p.motions, "characters")
        self.src_chars = {c.character_id: c for c in all_sources if fnmatch.fnmatch(c.character_id, p.sources)}
        clips = [m for m in read_records(p.motions, "motions") if m.character_id in self.src_chars]
        all_targets = read_records(p.characters, "characters")
        tgts = [c for c in all_targets if fnmatch.fnmatch(c.character_id, p.targets)]
        _refuse_empty(p.motions, p.characters, ("--sources", p.sources, all_sources, self.src_chars),
                      ("--targets", p.targets, all_targets, tgts), clips)
        humanoid = [t for t in tgts if len(humanoid_roles(t.bone_names)) >= MIN_ROLES]
        self.statuses = [StatusRecord(t.character_id, "retarget", "skipped",
                                      f"fewer than {MIN_ROLES} humanoid bone roles in its names", 0.0)
                         for t in tgts if t not in humanoid]
        self.items = [(self.src_chars[m.character_id], m, t) for m in clips for t in humanoid
                      if t.character_id != m.character_id]
        self.rows: dict[str, StatusRecord] = {}
        self.motions, self.reports, self.used = [], [], {}

    def name_of(self, item) -> str:
        return f"{item[1].motion_id} -> {item[2].character_id}"

    def done(self, run, item, ok, result) -> None:
        if not ok:
            return
        rec, report = result
        name = self.name_of(item)
        if rec is None:
            self.rows[name] = StatusRecord(name, "retarget", "failed", report, 0.0)
            return
        self.motions.append(rec)
        self.reports.append(report)
        self.used[item[2].character_id] = item[2]
        self.rows[name] = StatusRecord(name, "retarget", "ok", f"{len(report['mapped'])} roles mapped, "
                                       f"{len(report['target_unmapped'])} target bones at rest", 0.0)

    def nothing_made(self, statuses) -> bool:
        return False  # a run with no clip to keep still writes its status rows

    def write(self, run, statuses):
        statuses = [dataclasses.replace(self.rows[s.asset], seconds=s.seconds) if s.asset in self.rows else s
                    for s in statuses]
        self.reported = statuses
        chars = list(self.used.values())
        run.write_splits("characters", chars)
        run.write_splits("motions", self.motions)
        _write_physics(run, run.params.characters, chars)
        (run.out_dir / "retarget_report.json").write_text(json.dumps(self.reports, ensure_ascii=False, indent=1))
        self.clips, self.failed = len(self.motions), sum(s.status == "failed" for s in statuses)
        return statuses, {"pairs": len(self.items), "clips": len(self.motions), "characters": len(chars)}

    def counts(self, statuses) -> tuple[int, int]:
        return self.clips, self.failed


STAGE = Stage("retarget", RetargetParams, inputs=("characters", "motions"), item=_one,
              outputs=("characters", "motions", "status", *PHYSICS_TABLES), out_name="OUT folder",
              plan=RetargetPlan, in_key="motions", what="clip",  # fingerprints: the clips' dataset
              info=lambda p: {"motions": str(p.motions), "characters": str(p.characters)},
              command=("datagen", "retarget"), function="mimicbench.datagen.retarget.stage:run_command",
              step_reads=(("motions", ("characters", "motions")), ("characters", ("characters",))),
              step_writes=("characters", "motions"))


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
    ``out_dir`` (:func:`drive` with :data:`STAGE`): the targets (with their own rigid bodies and
    joints, an MMD file's physics), the clips (``<target>/<source>/<clip>``), a status row per pair
    and ``retarget_report.json`` (mapped and unmapped bones per pair). Returns a summary."""
    params = RetargetParams(str(motions_dir), str(characters_dir), str(out_dir), sources, targets, quiet=not progress)
    s = drive(STAGE, params)
    return {**s.details, "failed": s.failed, "statuses": list(s.statuses), "seconds": s.seconds}


def run_command(params: RetargetParams) -> StageSummary:
    """``mimicbench datagen retarget``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    from mimicbench.datagen.stage_runner import summarize_statuses

    s = drive(STAGE, params)
    if params.quiet:
        print(summarize_statuses(s.statuses))
    print(f"{s.details['clips']} clips on {s.details['characters']} characters ({s.details['pairs']} pairs) in "
          f"{params.out} in {s.seconds:.1f} s; report: {params.out}/retarget_report.json")
    return s
