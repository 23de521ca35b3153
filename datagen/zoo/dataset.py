"""Build a whole zoo dataset: plan, build every character (failures become status rows), write shards."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mimicbench.engines import Engine
from mimicbench.geometry.validation import expect, is_whole
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.datagen.zoo.params import EXPORT_FORMATS, ZooParams
from mimicbench.datagen.zoo.build import ZOO_VERSION, BuiltCharacter, build_character
from mimicbench.datagen.zoo.clips import CLIP_SETS
from mimicbench.datagen.zoo.card import character_summary, render_card, zoo_stats_from_summaries
from mimicbench.datagen.zoo.export_bvh import write_bvh
from mimicbench.datagen.zoo.export_obj import write_obj
from mimicbench.datagen.zoo.motions import FPS, MAX_FRAMES, NUM_FRAMES, RAMP_FRAMES
from mimicbench.datagen.zoo.plan import assign_splits, plan_zoo
from mimicbench.datagen.zoo.templates.humanoid import H2H_SKELETON_ID
from mimicbench.schemas.manifest import atomic_write_bytes
from mimicbench.schemas.shards import SPLITS

SPLIT_RULE = ("Split rule (stratified, deterministic; datagen/zoo/plan.py): per stratum (each category, the H2H "
              "family its own), IDs sorted by sha256; the first max(1, round(0.1 n)) go to test (the H2H family at "
              "least min(3, n - 1)), the next round(0.1 n) to val, the rest to train.")


def export_character(out: Path, built: BuiltCharacter, export: tuple[str, ...]) -> None:
    """Write ``export/<name>.obj``, ``export/<name>/<clip>.bvh`` and ``export/<name>.pmx`` (MMD model, apparel
    chains as rigid bodies and joints; name: the ID after ``zoo/``)."""
    r = built.record
    name = r.character_id.split("/", 1)[-1]
    if "obj" in export:
        write_obj(out / "export" / f"{name}.obj", r.vertices, r.faces, name)
    if "bvh" in export:
        for m in built.motions:
            write_bvh(out / "export" / name / f"{m.name}.bvh", r.bone_names, r.parents, r.keypoints,
                      built.skeleton.tails, m.transforms, m.fps)
    if "pmx" in export:
        from mimicbench.datagen.mmd.chain_physics import chain_physics
        from mimicbench.datagen.mmd.pmx_writer import write_pmx

        write_pmx(out / "export" / f"{name}.pmx", r, *chain_physics(r))


def clips_per_character_for(specs: list, clips_per_character: int, motions: int | None) -> list[int]:
    """Clips of each character: ``clips_per_character`` each, or ``motions`` in all spread evenly.

    With ``motions`` M over N characters, character i gets ``floor((i+1)M/N) - floor(iM/N)`` clips
    (so the counts differ by at most one and sum to M exactly); every character gets at least one.
    """
    n = len(specs)
    if motions is None:
        return [clips_per_character] * n
    if motions < n:
        raise ValueError(f"motions: expected at least one clip per character (>= {n}), got {motions}")
    return [(i + 1) * motions // n - i * motions // n for i in range(n)]


class ZooPlan(StagePlan):
    """Every planned character one item, built in plan order and streamed into the shards of its
    split as it comes (:meth:`done`), so memory holds a few hundred clips."""

    ordered = True

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        p = run.params
        self.specs = plan_zoo(p.num_characters, p.seed, p.categories)
        if not self.specs:
            raise ValueError(f"num_characters: expected >= 1, got {p.num_characters}")
        splits = assign_splits(self.specs)
        counts = clips_per_character_for(self.specs, p.clips_per_character, p.motions)
        self.items = [(spec, splits[spec.character_id], count) for spec, count in zip(self.specs, counts)]
        self.kwargs = {"out": run.out_dir, "export": p.export, "frames_per_clip": int(p.frames_per_clip),
                       "clip_set": p.clip_set}
        self.characters, self.clips = [], []  # small summaries for the card, not the arrays

    @property
    def what(self) -> str:
        return f"one of the {len(self.specs)} characters"

    def name_of(self, item) -> str:
        return item[0].character_id

    def start(self, run) -> None:
        self.streams = run.open_streams([(table, split) for table in ("characters", "motions") for split in SPLITS])

    def done(self, run, item, ok, result) -> None:
        if not ok:
            return
        record, motions_of = result
        self.streams["characters", record.split].add([record])
        self.streams["motions", record.split].add(motions_of)
        self.characters.append(character_summary(record))
        self.clips.extend((m.character_id, int(m.num_frames)) for m in motions_of)

    def nothing_made(self, statuses) -> bool:
        return not self.characters

    def abort(self, run, exc) -> None:
        for stream in getattr(self, "streams", {}).values():
            stream.abort()  # drops what it wrote

    def write(self, run, statuses):
        for stream in self.streams.values():
            stream.close()  # names its shards and lists them
        for s in statuses:
            s.seconds = 0.0  # timings vary run to run; keep the shards byte-identical
        characters, clips = self.characters, self.clips
        split_counts = {s: sum(1 for c in characters if c["split"] == s) for s in SPLITS}
        family = sum(1 for c in characters if c["skeleton_id"] == H2H_SKELETON_ID)
        self.stats = zoo_stats_from_summaries(characters, clips)
        self.card = (split_counts, family)
        failed = [s for s in statuses if s.status != "ok"]

        def spread(key: str) -> list:  # min, mean, max over the characters
            v = np.array([c[key] for c in characters])
            return [int(v.min()), float(v.mean()), int(v.max())]

        return statuses, {
            "out": str(run.out_dir), "characters": len(characters), "motions": len(clips),
            "frames": int(sum(f for _, f in clips)), "failed": len(failed),
            "failures": [f"{s.asset}: {s.reason}" for s in failed],
            "by_category": {k: v["characters"] for k, v in self.stats.items() if k != "all"}, "splits": split_counts,
            "h2h_family": family, "joints": spread("joints"), "faces": spread("faces")}

    def after(self, run) -> None:
        split_counts, family = self.card
        atomic_write_bytes(run.out_dir / "CARD.md", render_card(self.stats, run.config, split_counts, family).encode())

    def counts(self, statuses) -> tuple[int, int]:
        return len(self.characters), sum(s.status != "ok" for s in statuses)


def _check(p: ZooParams) -> None:
    expect(all(e in EXPORT_FORMATS for e in p.export), "export", f"some of {EXPORT_FORMATS}", p.export)
    expect(p.clips_per_character >= 1, "clips_per_character", ">= 1", p.clips_per_character)
    expect(is_whole(p.frames_per_clip) and RAMP_FRAMES < p.frames_per_clip <= MAX_FRAMES, "frames_per_clip",
           f"an integer from {RAMP_FRAMES + 1} to {MAX_FRAMES}", p.frames_per_clip)
    expect(is_whole(p.seed) and p.seed >= 0, "seed", "an integer >= 0", p.seed)
    expect(p.clip_set in CLIP_SETS, "clip_set", f"one of {list(CLIP_SETS)}", p.clip_set)


def build_zoo(out_dir, num_characters: int, seed: int = 0, categories: list[str] | None = None,
              clips_per_character: int = 3, export: tuple[str, ...] = (), progress: bool = True,
              motions: int | None = None, frames_per_clip: int = NUM_FRAMES, engine: Engine | None = None,
              jobs: int = 1, clip_set: str = "default") -> dict:
    """Generate a procedural zoo into ``out_dir`` (:func:`drive` with :data:`STAGE`).

    Writes ``characters/`` and ``motions/`` shards (one set per split; an empty split gets an
    empty shard so a rebuild replaces older data), a ``status`` table (split ``zoo``, seconds 0 so
    the bytes depend only on the arguments), the manifest, ``CARD.md`` and the ``export`` files.
    Characters are built by ``engine`` (default: the local engine with ``jobs`` processes) and
    streamed into the shards in plan order, so memory holds a few hundred clips. A zoo in which
    every character failed writes nothing (:class:`DatasetError` says why).

    Args:
        motions: total clips, spread evenly over the characters (instead of ``clips_per_character`` each).
        frames_per_clip: frames of every clip at 30 fps.
        clip_set: which clips (``mimicbench.datagen.zoo.clips.CLIP_SETS``); in the config only when not ``default``.

    Returns:
        A summary dict: ``characters``, ``motions``, ``frames``, ``failed``, ``by_category``,
        ``splits``, ``h2h_family``, ``joints`` and ``faces`` (min, mean, max), ``seconds``, ``out``.
    """
    params = ZooParams(str(out_dir), num_characters=int(num_characters), seed=seed, categories=categories,
                       clips_per_character=clips_per_character, frames_per_clip=frames_per_clip,
                       motions=None if motions is None else int(motions), clip_set=clip_set, jobs=jobs,
                       export=tuple(export or ()), quiet=not progress)
    s = drive(STAGE, params, engine=engine)
    return {**s.details, "seconds": s.seconds}


def _build_one(item, out: Path, export: tuple[str, ...], frames_per_clip: int, clip_set: str = "default"):
    """Build one planned character (and its export files); return (record, motions)."""
    spec, split, clips = item
    built = build_character(spec, split, clips, frames_per_clip, clip_set)
    if export:
        export_character(out, built, export)
    return built.record, built.motions


STAGE = Stage("zoo", ZooParams, inputs=(), item=_build_one, outputs=("characters", "motions", "status"),
              out_name="--out folder", generator="mimicbench.zoo", title="the zoo", plan=ZooPlan, check=_check,
              constants=(("generator", "mimicbench.zoo"), ("zoo_version", ZOO_VERSION), ("fps", FPS),
                         ("h2h_skeleton_id", H2H_SKELETON_ID), ("split_rule", SPLIT_RULE)),
              what="character", command=("zoo",), function="mimicbench.datagen.zoo.dataset:run_command",
              versions=("mimicbench.datagen.zoo.build:ZOO_VERSION",), step_writes=("characters", "motions"))


def run_command(params: ZooParams) -> StageSummary:
    """``mimicbench zoo``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    s = drive(STAGE, params)
    d = s.details
    for f in d["failures"] if params.quiet else ():  # else the driver listed them
        print(f"  FAILED {f}")
    if not params.no_contact_sheet:
        from mimicbench.datagen.zoo.card import add_contact_sheet

        sheet = add_contact_sheet(params.out)
        print(f"contact sheet: {sheet['path'] or 'not rendered: ' + sheet['error']}")
    cats_txt = ", ".join(f"{k} {v}" for k, v in d["by_category"].items())
    print(f"zoo: {d['characters']} characters ({cats_txt}), {d['motions']} clips, {d['frames']} frames; "
          f"joints {d['joints'][0]}-{d['joints'][2]}, faces {d['faces'][0]}-{d['faces'][2]}; "
          f"H2H family {d['h2h_family']}; splits {d['splits']}; {d['failed']} failed; "
          f"{s.seconds:.1f} s -> {d['out']} (see CARD.md)")
    return s
