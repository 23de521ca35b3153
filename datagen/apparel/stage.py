"""The apparel stage over a dataset: ``mimicbench datagen apparel IN OUT``. Beside every kinematic
clip of a character with apparel bones goes a simulated ``<clip>@sim``, its quality in the
character's ``meta['apparel']['clips']``; chains that escape are re-settled (``resettles`` in the quality,
:mod:`mimicbench.datagen.apparel.simulate`) and a clip that still explodes is a failed status row. Resume:
FORMAT.md, "Stages and resume". Correspondences (``pairs``) are not carried over.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from mimicbench.datagen.apparel.clip_bounds import check_clip_bounds
from mimicbench.datagen.apparel.params import ApparelParams
from mimicbench.datagen.apparel.quality import over_jitter_bound
from mimicbench.datagen.apparel.selection import apparel_vertex_mask, bones_matching, selection_problem
from mimicbench.datagen.apparel.card import write_apparel_card
from mimicbench.datagen.apparel.setup import SIM_VERSION, physics_step, simulate_motion
from mimicbench.datagen.apparel.world_cache import character_world, close_cached_world
from mimicbench.datagen.apparel.stage_params import ApparelOptions
from mimicbench.datagen.stage_runner import NO_ROWS, Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.engines import Engine
from mimicbench.schemas.errors import UserError
from mimicbench.schemas.motion import SIM_SUFFIX
from mimicbench.schemas.rigid_body import PHYSICS_TABLES
from mimicbench.schemas.shards import has_table, read_records, splits_of
from mimicbench.schemas.status import StatusRecord


def is_simulated(motion) -> bool:
    """True for a motion this stage wrote (name ``<clip>@sim``)."""
    return motion.name.endswith(SIM_SUFFIX)


def _simulate_one(item, params: ApparelParams, physics_fps: float, relax: int):
    record, bones, vertices, motion, file_rows = item
    if file_rows is not None:  # the character's own rigid bodies and joints (an MMD file)
        from mimicbench.datagen.apparel.file_physics import simulate_file_motion

        sim, quality = simulate_file_motion(record, *file_rows, motion, bones, vertices, physics_fps, relax,
                                            params.simulation)
    else:
        physics, world = character_world(record, bones, vertices, params, physics_step(physics_fps, motion.fps))
        sim, quality = simulate_motion(record, physics, motion, params, physics_fps, relax, world)
    check_clip_bounds(sim.transforms, quality)  # a clip out of bounds fails its item with the bound named
    return sim, quality


def apparel_config(options: ApparelOptions) -> dict:
    """The config of a run: physics rate, relaxation, the simulation parameters, the bone patterns."""
    return {"physics_fps": float(options.fps), "relax_frames": int(options.relax_frames),
            "params": options.simulation_params().to_json(),
            "apparel_bones": list(options.apparel_bones) if options.apparel_bones else None}


def _apparel_masks(record, patterns: list[str] | None) -> tuple[np.ndarray, np.ndarray]:
    if len(record.faces) == 0:  # a skeleton-only source (BVH) has no body to collide with
        return np.zeros(record.num_joints, bool), np.zeros(0, bool)
    if not patterns:
        return np.asarray(record.apparel_bone_mask, bool), np.asarray(record.apparel_vertex_mask, bool)
    bones = bones_matching(record.bone_names, patterns)
    return bones, apparel_vertex_mask(record.weights, bones)


def _file_physics(in_dir: Path, patterns: list[str] | None) -> dict:
    """``{character_id: (rigid bodies, joints)}`` in file order for characters that have rigid
    bodies (their physics comes from the file, :mod:`mimicbench.datagen.apparel.file_physics`); none when
    ``--apparel-bones`` patterns choose the apparel (then the chain defaults apply)."""
    if patterns or not has_table(in_dir, "rigid_bodies"):
        return {}
    rows: dict[str, tuple[list, list]] = {}
    for b in read_records(in_dir, "rigid_bodies"):
        rows.setdefault(b.character_id, ([], []))[0].append(b)
    for j in read_records(in_dir, "joints") if has_table(in_dir, "joints") else []:
        if j.character_id in rows:
            rows[j.character_id][1].append(j)
    return {c: (sorted(b, key=lambda r: r.body_index), sorted(j, key=lambda r: r.joint_index))
            for c, (b, j) in rows.items()}


def _previous_work(run: StageRun, progress: bool) -> tuple[dict, dict]:
    """Simulated motions and their quality already in OUT, made with the same fingerprints."""
    old, why = run.previous()
    if why is not None:
        if why != NO_ROWS and progress:
            print(f"apparel: {run.out_dir} holds a run that does not match ({why}); simulating every clip again")
        return {}, {}
    sims = {m.motion_id: m for m in read_records(run.out_dir, "motions", allow_incomplete=True) if is_simulated(m)}
    quality = {}
    for r in read_records(run.out_dir, "characters", allow_incomplete=True):
        for clip, q in ((r.meta or {}).get(STAGE.name, {}).get("clips") or {}).items():
            quality[f"{r.character_id}/{clip}{SIM_SUFFIX}"] = q
    return {k: v for k, v in sims.items() if k in quality}, quality


class ApparelPlan(StagePlan):
    """Every kinematic clip of a character with apparel bones one item (not those OUT already holds
    from a run with the same fingerprints), ``batch`` clips at a time; the dataset is written after
    each batch (:meth:`batch_done`), so a killed run keeps what it simulated."""

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        o, in_dir = run.params, run.in_dir
        if not has_table(in_dir, "characters") or not has_table(in_dir, "motions"):
            raise UserError(f"{in_dir}: expected a dataset with characters and motions tables (manifest.json)")
        self.params = o.simulation_params()
        self.patterns = list(o.apparel_bones) if o.apparel_bones else None
        self.sims, self.quality = _previous_work(run, not o.quiet)
        self.records = read_records(in_dir, "characters")
        self.kinematic = [m for m in read_records(in_dir, "motions") if not is_simulated(m)]
        self.masks = {r.character_id: _apparel_masks(r, self.patterns) for r in self.records}
        by_id = {r.character_id: r for r in self.records}
        unknown = sorted({m.character_id for m in self.kinematic} - set(by_id))
        if unknown:
            raise UserError(f"{in_dir}: motions of unknown characters {unknown[:3]}; expected every motion's "
                            f"character_id in the characters table")
        self.reused_clips, file_rows = len(self.sims), _file_physics(in_dir, self.patterns)
        todo = [m for m in self.kinematic if self.masks[m.character_id][0].any()
                and m.motion_id + SIM_SUFFIX not in self.sims]
        unusable = {cid: problem for cid, (bones, vertices) in self.masks.items()
                    if bones.any() and cid not in file_rows
                    and (problem := selection_problem(by_id[cid].bone_names, by_id[cid].parents, bones, vertices))}
        self.statuses = [StatusRecord(m.motion_id, STAGE.name, "failed", unusable[m.character_id], 0.0) for m in todo
                         if m.character_id in unusable]  # the kinematic clip stays; a fixed selection re-runs them
        self.items = [(by_id[m.character_id], *self.masks[m.character_id], m, file_rows.get(m.character_id))
                      for m in todo if m.character_id not in unusable]
        self.kwargs = {"params": self.params, "physics_fps": o.fps, "relax": o.relax_frames}
        self.batch, self.run = o.batch, run

    def name_of(self, item) -> str:
        return item[3].motion_id

    def batches(self):
        for i in range(0, max(len(self.items), 1), self.batch):
            yield STAGE.name, self.items[i:i + self.batch]

    def done(self, run, item, ok, result) -> None:
        if ok:
            sim, q = result
            self.sims[sim.motion_id] = sim
            self.quality[sim.motion_id] = q

    def batch_done(self, run, statuses) -> None:
        self.rows = _write(run, self.records, self.kinematic, self.masks, self.sims, self.quality, statuses,
                           self.patterns)

    def nothing_made(self, statuses) -> bool:
        return False  # a failed clip keeps its kinematic clip and gets a status row

    def write(self, run, statuses):
        close_cached_world()
        qs = list(self.quality.values())

        def mean(key):
            return float(np.mean([q[key] for q in qs])) if qs else None

        self.failed = sum(s.status == "failed" for s in statuses)
        self.simulated = sum(s.status == "ok" for s in statuses)
        return self.rows, {
            "characters": sum(1 for b, _ in self.masks.values() if b.any()), "clips": len(self.kinematic),
            "simulated": self.simulated, "reused": self.reused_clips, "failed": self.failed,
            "resettled": sum(q["resettles"] > 0 for q in qs),
            "over_jitter_bound": sorted(k for k, q in self.quality.items() if over_jitter_bound(q)),
            "new_inside_pct_mean": mean("new_inside_pct"), "inside_pct_mean": mean("inside_pct"),
            "secondary_motion_pct_mean": mean("secondary_motion_pct"),
            "max_edge_stretch": max((q["max_edge_stretch"] for q in qs), default=None)}

    def after(self, run) -> None:
        write_apparel_card(run.out_dir, {k.removesuffix(SIM_SUFFIX): q for k, q in self.quality.items()})

    def counts(self, statuses) -> tuple[int, int]:
        return self.simulated + self.reused_clips, self.failed


STAGE = Stage("apparel", ApparelOptions, inputs=("characters", "motions", *PHYSICS_TABLES),
              item=_simulate_one, outputs=("characters", "motions", "status"), copies=PHYSICS_TABLES,
              made_by="motions", title="the apparel stage", plan=ApparelPlan, out_key="out_dataset",
              in_key="in_dataset", constants=(("version", SIM_VERSION),), config=apparel_config,
              info=lambda o: {"source": str(o.in_dataset)}, what="clip", command=("datagen", "apparel"),
              function="mimicbench.datagen.apparel.stage:run_command",
              versions=("mimicbench.datagen.apparel.setup:SIM_VERSION",
                        "mimicbench.datagen.apparel.file_physics:FILE_PHYSICS_VERSION"),
              step_reads=(("in_dataset", ("characters", "motions")),), step_writes=("characters", "motions"))


def simulate_dataset(in_dir, out_dir, physics_fps: float = 240.0, relax: int = 30, params: ApparelParams | None = None,
                     apparel_bones: list[str] | None = None, jobs: int = 1, batch: int = 16,
                     progress: bool = True, engine: Engine | None = None) -> dict:
    """Simulate the apparel of every clip of ``in_dir`` into ``out_dir`` (:func:`drive` with
    :data:`STAGE`; a re-run resumes).

    Args:
        physics_fps: physics steps per second (each frame gets ``ceil(physics_fps / clip fps)``).
        relax: relaxation frames before each clip (simulated, dropped).
        params: chain and scene parameters (defaults when None).
        apparel_bones: glob patterns on bone names choosing the apparel bones (default: each
            character's ``apparel_bone_mask``); the apparel vertex mask then follows the weights.
        jobs: worker processes. batch: clips between two writes.
        engine: where clips are simulated (:mod:`mimicbench.engines`; default the local engine with
            ``jobs`` processes; the output does not depend on it).

    Returns:
        Summary: characters, clips simulated, reused, failed, resettled (clips of OUT with a
        re-settled frame), over_jitter_bound (the simulated clips' motion ids whose peak apparel
        acceleration is over :data:`~mimicbench.datagen.apparel.quality.JITTER_RATIO` times their kinematic peaks,
        :func:`~mimicbench.datagen.apparel.quality.over_jitter_bound`), mean quality, seconds, statuses.
    """
    options = ApparelOptions(str(in_dir), str(out_dir), fps=physics_fps, relax_frames=relax,
                             params=params or ApparelParams(), apparel_bones=list(apparel_bones) if apparel_bones
                             else None, jobs=jobs, quiet=not progress, batch=batch)
    s = drive(STAGE, options, engine=engine)
    return {**s.details, "seconds": s.seconds, "statuses": list(s.statuses)}


def _write(run: StageRun, records, kinematic, masks, sims, quality, statuses, patterns) -> list[StatusRecord]:
    """Write characters (masks, meta), motions (kinematic, then each one's simulated clip), status;
    return the status rows."""
    chars = []
    for r in records:
        bones, vertices = masks[r.character_id]
        meta = dict(r.meta or {})
        if bones.any():
            clips = {m.name: quality[m.motion_id + SIM_SUFFIX] for m in kinematic
                     if m.character_id == r.character_id and m.motion_id + SIM_SUFFIX in quality}
            meta[STAGE.name] = {"version": SIM_VERSION, "apparel_bones": patterns, "clips": clips}
        if len(r.faces):
            r = dataclasses.replace(r, apparel_bone_mask=bones, apparel_vertex_mask=vertices)
        chars.append(dataclasses.replace(r, meta=meta))
    run.write_splits("characters", chars, splits_of(run.in_dir, "characters"))
    run.write_splits("motions", [x for m in kinematic for x in (m, sims.get(m.motion_id + SIM_SUFFIX)) if x is not None],
                     splits_of(run.in_dir, "motions"))
    latest = {s.asset: s for s in statuses}
    rows = []
    for m in kinematic:
        sim_id = m.motion_id + SIM_SUFFIX
        if sim_id in sims and m.motion_id not in latest:  # simulated by an earlier run
            rows.append(StatusRecord(m.motion_id, STAGE.name, "ok", "", 0.0))
        elif m.motion_id in latest:
            rows.append(dataclasses.replace(latest[m.motion_id], seconds=0.0))
    rows += [StatusRecord(r.character_id, STAGE.name, "skipped", "no mesh" if len(r.faces) == 0 else "no apparel bones", 0.0)
             for r in records if not masks[r.character_id][0].any()]
    run.write_status(rows)
    return rows


def run_command(params: ApparelOptions) -> StageSummary:
    """``mimicbench datagen apparel``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    from mimicbench.datagen.apparel.quality import JITTER_RATIO

    summary = drive(STAGE, params)
    s = summary.details

    def fmt(x, digits=3):
        return "n/a" if x is None else round(x, digits)

    print(f"{s['simulated']} clips simulated, {s['reused']} reused, {s['failed']} failed, {s['resettled']} "
          f"re-settled on {s['characters']} "
          f"characters with apparel in {summary.seconds:.1f} s; apparel inside the body {fmt(s['inside_pct_mean'])} % "
          f"(new {fmt(s['new_inside_pct_mean'])} %), secondary motion {fmt(s['secondary_motion_pct_mean'])} % of "
          f"height, max edge stretch {fmt(s['max_edge_stretch'])} -> {params.out_dataset}")
    if s["over_jitter_bound"]:
        n = len(s["over_jitter_bound"])
        print(f"{n} {'clip peaks' if n == 1 else 'clips peak'} above {JITTER_RATIO:g}x the acceleration of the kinematic apparel and "
              f"of the body that touches it (jitter, not a limb's strike): {', '.join(s['over_jitter_bound'][:5])}"
              f"{' ...' if len(s['over_jitter_bound']) > 5 else ''}; their quality is in the characters' "
              f"meta['apparel']")
    share = s["failed"] / max(1, s["simulated"] + s["reused"] + s["failed"])
    if s["failed"]:
        print(f"{s['failed']} failed clips ({100 * share:.1f} % of the clips, --max-failed "
              f"{100 * params.max_failed:g} %): see the status rows in {params.out_dataset}/status; their kinematic "
              f"clips are kept")
    return dataclasses.replace(summary, exit_code=1 if share > params.max_failed else 0)
