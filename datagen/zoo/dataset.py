"""Build a whole zoo dataset: plan, build every character (failures become status rows), write shards."""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from mimicbench.engines import Engine
from mimicbench.geometry.validation import expect, is_whole
from mimicbench.datagen.stage_runner import Stage, StageRun, omitted_unless_set, run_stage
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

EXPORT_FORMATS = ("obj", "bvh", "pmx")
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


def build_zoo(out_dir, num_characters: int, seed: int = 0, categories: list[str] | None = None,
              clips_per_character: int = 3, export: tuple[str, ...] = (), progress: bool = True,
              motions: int | None = None, frames_per_clip: int = NUM_FRAMES, engine: Engine | None = None,
              jobs: int = 1, clip_set: str = "default") -> dict:
    """Generate a procedural zoo into ``out_dir``.

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
    start = time.perf_counter()
    export = tuple(export or ())
    expect(all(e in EXPORT_FORMATS for e in export), "export", f"some of {EXPORT_FORMATS}", export)
    expect(clips_per_character >= 1, "clips_per_character", ">= 1", clips_per_character)
    expect(is_whole(frames_per_clip) and RAMP_FRAMES < frames_per_clip <= MAX_FRAMES, "frames_per_clip",
           f"an integer from {RAMP_FRAMES + 1} to {MAX_FRAMES}", frames_per_clip)
    expect(is_whole(seed) and seed >= 0, "seed", "an integer >= 0", seed)
    expect(clip_set in CLIP_SETS, "clip_set", f"one of {list(CLIP_SETS)}", clip_set)
    out = Path(out_dir)
    specs = plan_zoo(num_characters, seed, categories)
    if not specs:
        raise ValueError(f"num_characters: expected >= 1, got {num_characters}")
    clip_counts = clips_per_character_for(specs, clips_per_character, motions)
    splits = assign_splits(specs)
    run = StageRun(STAGE, ZooParams(seed=int(seed), num_characters=int(num_characters),
                                    categories=list(categories) if categories else None,
                                    clips_per_character=int(clips_per_character), frames_per_clip=int(frames_per_clip),
                                    motions=None if motions is None else int(motions), clip_set=clip_set), out)
    items = [(spec, splits[spec.character_id], count) for spec, count in zip(specs, clip_counts)]
    work = partial(STAGE.item, out=out, export=export, frames_per_clip=int(frames_per_clip), clip_set=clip_set)
    characters, clips = [], []  # small summaries for the card, not the arrays
    with run.streams([(table, split) for table in ("characters", "motions") for split in SPLITS]) as streams:

        def on_done(i: int, ok: bool, result) -> None:
            if not ok:
                return
            record, motions_of = result
            streams["characters", record.split].add([record])
            streams["motions", record.split].add(motions_of)
            characters.append(character_summary(record))
            clips.extend((m.character_id, int(m.num_frames)) for m in motions_of)

        _, statuses = run_stage(items, work, "zoo", name_of=lambda it: it[0].character_id, jobs=jobs,
                                progress=progress, on_done=on_done, engine=engine, ordered=True, keep_results=False)
        if not characters:
            raise run.abandon(statuses, f"one of the {len(specs)} characters")  # begin() has not run: nothing written
        for s in statuses:
            s.seconds = 0.0  # timings vary run to run; keep the shards byte-identical
        run.begin()  # the streams are named and listed when the block ends
    run.write_status(statuses)
    run.finish()
    split_counts = {s: sum(1 for c in characters if c["split"] == s) for s in SPLITS}
    family = sum(1 for c in characters if c["skeleton_id"] == H2H_SKELETON_ID)
    stats = zoo_stats_from_summaries(characters, clips)
    atomic_write_bytes(out / "CARD.md", render_card(stats, run.config, split_counts, family).encode())
    failed = [s for s in statuses if s.status != "ok"]

    def spread(key: str) -> list:  # min, mean, max over the characters
        v = np.array([c[key] for c in characters])
        return [int(v.min()), float(v.mean()), int(v.max())]

    return {"out": str(out), "characters": len(characters), "motions": len(clips),
            "frames": int(sum(f for _, f in clips)), "failed": len(failed), "failures": [f"{s.asset}: {s.reason}" for s in failed],
            "by_category": {k: v["characters"] for k, v in stats.items() if k != "all"}, "splits": split_counts,
            "h2h_family": family, "joints": spread("joints"), "faces": spread("faces"), "seconds": time.perf_counter() - start}


def _build_one(item, out: Path, export: tuple[str, ...], frames_per_clip: int, clip_set: str = "default"):
    """Build one planned character (and its export files); return (record, motions)."""
    spec, split, clips = item
    built = build_character(spec, split, clips, frames_per_clip, clip_set)
    if export:
        export_character(out, built, export)
    return built.record, built.motions


@dataclass(frozen=True)
class ZooParams:
    """What a zoo is built from (:func:`build_zoo`), in the order of its config."""

    generator: str = "mimicbench.zoo"
    zoo_version: int = ZOO_VERSION
    seed: int = 0
    num_characters: int = 1
    categories: list | None = None
    clips_per_character: int = 3
    fps: int = FPS
    frames_per_clip: int = NUM_FRAMES
    h2h_skeleton_id: str = H2H_SKELETON_ID
    split_rule: str = SPLIT_RULE
    motions: int | None = omitted_unless_set(None)
    clip_set: str = omitted_unless_set("default")


STAGE = Stage("zoo", ZooParams, inputs=(), item=_build_one, outputs=("characters", "motions", "status"),
              out_name="--out folder", generator="mimicbench.zoo", title="the zoo")
