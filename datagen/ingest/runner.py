"""Ingest assets into a dataset, additively: Blender children (:mod:`.blender_pool`) for glTF, FBX,
BVH, OBJ and .blend, :mod:`mimicbench.datagen.mmd` for MMD files. Each child result is cached in
``DATASET/.ingest`` under a key of content hash and options (:mod:`.identity`), so a re-run skips
assets already done; every failure is a status row (split ``ingest``). This run's assets replace
only their own rows (by character ID).
"""
from __future__ import annotations

import fnmatch
import json
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from queue import Queue

import numpy as np
from tqdm.auto import tqdm

from mimicbench.datagen.ingest import blender_pool
from mimicbench.datagen.ingest.asset_paths import BLENDER_SUFFIXES, FOLDER_SUFFIXES, expand_asset_paths
from mimicbench.datagen.ingest.bvh_units import PLAUSIBLE_HEIGHT_M, auto_bvh_scale, bvh_rest_height
from mimicbench.datagen.ingest.category import infer_category
from mimicbench.datagen.ingest.clip_length import MAX_CLIP_FRAMES, check_clip_frames
from mimicbench.datagen.ingest.identity import cache_key, character_id_for, file_sha256, skeleton_id
from mimicbench.datagen.ingest.job import run_job, status_of
from mimicbench.datagen.ingest.uris import external_uri_problems
from mimicbench.datagen.mmd.frame import MMD_UNIT_METRES
from mimicbench.datagen.splits import split_of
from mimicbench.datagen.stage_runner import Stage, StageRun, not_a_param
from mimicbench.runtime.argtypes import MAX_JOBS
from mimicbench.runtime.errors import UserError
from mimicbench.geometry.kinematics import transforms_to_array
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.geometry.validation import expect, is_whole
from mimicbench.schemas.character import CATEGORIES, CharacterRecord
from mimicbench.schemas.finite import nonfinite_arrays
from mimicbench.schemas.folder_lock import hold
from mimicbench.schemas.manifest import MANIFEST
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.weights import SparseWeights

CACHE = ".ingest"
SUPPORTED = BLENDER_SUFFIXES
EXPORT_FORMATS = ("obj", "bvh")
DEFAULT_BVH_SCALE = "auto"  # metres per BVH unit from the rest skeleton (datagen/ingest/bvh_units.py)
PLAUSIBLE_EXTENT_M = (0.05, 30.0)  # a meshed character's largest rest extent outside this: warn (--mesh-unit)


def _positive(x) -> bool:
    """A finite number > 0 (not a bool)."""
    return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x) and x > 0


@dataclass
class IngestOptions:
    """What ``datagen ingest`` may be asked (the stage's params; ``--help`` says each); :meth:`check`
    says what is allowed. ``mmd_unit``: metres per MMD unit; ``mesh_unit``: metres per unit of the
    scene Blender imports (every length times it; a rest extent outside :data:`PLAUSIBLE_EXTENT_M`
    warns); ``split_file``: JSON split -> character IDs; ``assets_per_process``: before a fresh Blender."""

    jobs: int = not_a_param(1)
    timeout: float = 300.0
    bvh_scale: float | str = DEFAULT_BVH_SCALE
    allow_external_uris: bool = False
    export: tuple = not_a_param(())
    split: str | None = None
    split_file: str | None = None
    assets_per_process: int = not_a_param(50)
    category_map: dict = field(default_factory=dict)
    mmd_unit: float = MMD_UNIT_METRES
    mesh_unit: float = 1.0
    max_clip_frames: int = MAX_CLIP_FRAMES

    def __post_init__(self):
        self.export, self.category_map = tuple(self.export), dict(self.category_map or {})

    def check(self) -> None:
        """Raise ValueError naming the option and the allowed range."""
        expect(isinstance(self.jobs, int) and 1 <= self.jobs <= MAX_JOBS, "--jobs",
                f"a whole number of Blender processes from 1 to {MAX_JOBS}", self.jobs)
        expect(self.timeout > 0, "--timeout", "seconds per asset greater than 0", self.timeout)
        expect(self.bvh_scale == "auto" or (isinstance(self.bvh_scale, (int, float)) and self.bvh_scale > 0),
                "--bvh-scale", "'auto' or metres per BVH unit greater than 0 (0.01 for centimetres)", self.bvh_scale)
        expect(_positive(self.mmd_unit), "--mmd-unit",
                "metres per MMD unit, a finite number greater than 0 (MMD's usual 0.08)", self.mmd_unit)
        expect(_positive(self.mesh_unit), "--mesh-unit", "metres per unit of the imported scene, a finite number "
                "greater than 0 (1: glTF's metres; 0.01 for a file authored in centimetres)", self.mesh_unit)
        expect(is_whole(self.max_clip_frames) and self.max_clip_frames >= 1, "--max-clip-frames",
                f"a whole number of frames of at least 1 (default {MAX_CLIP_FRAMES})", self.max_clip_frames)
        expect(isinstance(self.assets_per_process, int) and self.assets_per_process >= 1, "assets_per_process",
                "at least 1", self.assets_per_process)
        unknown = [x for x in self.export if x not in EXPORT_FORMATS]
        expect(not unknown, "--export", f"a comma-separated list of {', '.join(EXPORT_FORMATS)}", unknown)
        bad = {k: v for k, v in self.category_map.items() if v not in CATEGORIES}
        expect(not bad, "--category-map", f"categories of {', '.join(CATEGORIES)}", bad)
        expect(self.split is None or self.split_file is None, "--split and --split-file", "one of them, not both",
                self.split_file)
        expect(self.split in (None, "train", "val", "test"), "--split", "train, val or test", self.split)

    def child_options(self, asset: Path) -> dict:
        """The options that change what a child writes for ``asset`` (part of its cache key); the
        clip length bound only when it is not the default (so default cache keys stay as they were)."""
        out = {"bvh_scale": self.bvh_scale_for(asset)[0]} if asset.suffix.lower() == ".bvh" else {}
        if self.max_clip_frames != MAX_CLIP_FRAMES:
            out["max_clip_frames"] = int(self.max_clip_frames)
        return out

    def bvh_scale_for(self, asset: Path) -> tuple[float, dict]:
        """Metres per unit of the BVH file ``asset`` and how it was chosen (``--bvh-scale``)."""
        if self.bvh_scale != "auto":
            return float(self.bvh_scale), {"bvh_scale_source": "--bvh-scale"}
        height = bvh_rest_height(asset)
        scale, unit, plausible = auto_bvh_scale(height)
        return scale, {"bvh_scale_source": "auto", "bvh_unit": unit, "bvh_rest_height_units": round(height, 4),
                       "bvh_unit_plausible": plausible}


STAGE = Stage("ingest", IngestOptions, inputs=(), item=run_job, outputs=("characters", "motions", "status"),
              out_name="--out folder")


def category_from_map(asset: Path, category_map: dict | None) -> str | None:
    """The first glob or file stem in the map that matches the asset, else None."""
    for pattern, category in (category_map or {}).items():
        if fnmatch.fnmatch(asset.name, pattern) or fnmatch.fnmatch(str(asset), pattern) or asset.stem == pattern:
            return category
    return None


def reproduction_error(char: CharacterRecord, transforms: np.ndarray, scale: np.ndarray | None, frames: np.ndarray,
                       evaluated: np.ndarray) -> dict:
    """Mean and max distance (percent of height) between the stored clip posed by LBS and the mesh
    Blender evaluated at ``frames`` in a second import of the file (:func:`.blender_child._reproduce`)."""
    if not len(char.vertices) or not char.height:
        return {}
    pred = linear_blend_skinning(char.vertices, char.keypoints, char.weights, transforms[frames],
                                 None if scale is None else scale[frames])
    d = np.linalg.norm(pred - evaluated, axis=-1) / char.height * 100
    return {"mean_pct": round(float(d.mean()), 5), "max_pct": round(float(d.max()), 5),
            "frames": [int(f) for f in frames]}


def records_from_cache(asset: Path, cache: Path, key: str, character_id: str, split: str,
                       category_map: dict | None = None, bvh_scale: tuple[float, dict] | None = None,
                       mesh_unit: float = 1.0) -> tuple[CharacterRecord, list[MotionRecord]]:
    """Character and motion records of one cached child result.

    ``mesh_unit`` (metres per unit of the scene Blender imported; ignored for BVH, which has
    ``bvh_scale``) multiplies every length: vertices, joints, clip translations. The cache holds
    the file's own units, so changing it needs no new Blender run.
    """
    meta = json.loads((cache / f"{key}.json").read_text())
    d = dict(np.load(cache / f"{key}.npz"))
    unit = 1.0 if asset.suffix.lower() == ".bvh" else float(mesh_unit)
    if unit != 1.0:
        d = _scaled_lengths(d, unit)
    verts = d["vertices"].astype(np.float32)
    k = len(meta["bone_names"])
    w = SparseWeights.from_dense(d["weights"]) if len(verts) else \
        SparseWeights(np.zeros((0, 8), np.int32), np.zeros((0, 8), np.float32), k)
    height = float(np.ptp(verts[:, 1])) if len(verts) else None
    parents = d["parents"].astype(np.int32)
    mapped = category_from_map(asset, category_map)
    pose_for_category = d["default_keypoints"] if "default_keypoints" in d else d["keypoints"]
    guess, evidence = infer_category(meta["bone_names"], parents, pose_for_category)
    category = mapped or guess
    info = {"blender": meta.get("blender"), "meshes": meta.get("meshes"), "clips": meta["clips"],
            "applied_modifiers": meta.get("applied_modifiers", []), "unweighted_vertices": meta.get("unweighted_vertices", 0),
            "default_pose_bones": meta.get("default_pose_bones", 0), "cache_key": key}
    if meta.get("left_out_vertices"):  # unweighted vertices on no bone: not stored (FORMAT.md)
        info["left_out_vertices"] = meta["left_out_vertices"]
    if asset.suffix.lower() == ".bvh":
        info["bvh_scale"], unit_evidence = bvh_scale
        info.update(unit_evidence, skeleton_height_m=round(float(np.ptp(d["keypoints"][:, 1])), 4))
    else:
        info["metres_per_unit"] = unit
    char = CharacterRecord(
        character_id=character_id, category=category, source=str(asset), split=split, vertices=verts,
        faces=d["faces"].astype(np.int32), keypoints=d["keypoints"].astype(np.float32), parents=parents,
        bone_names=meta["bone_names"], weight_indices=w.indices, weight_values=w.values,
        apparel_vertex_mask=np.zeros(len(verts), bool), apparel_bone_mask=np.zeros(k, bool),
        bone_roles=None, skeleton_id=skeleton_id(meta["bone_names"], parents), height=height,
        meta={"ingest": info, "category": {"value": category, "source": "map" if mapped else "inferred",
                                           "inferred": guess, "evidence": evidence}})
    motions = []
    for ci, clip in enumerate(meta["clips"]):
        t = d[f"clip{ci}_transforms"]
        scale = d[f"clip{ci}_scale"] if f"clip{ci}_scale" in d else None
        if f"clip{ci}_eval_vertices" in d:
            clip["reproduction_error"] = reproduction_error(char, t, scale, d[f"clip{ci}_eval_frames"],
                                                            d[f"clip{ci}_eval_vertices"])
        motions.append(MotionRecord(f"{character_id}/{clip['name']}", character_id, clip["name"], split,
                                    float(clip["fps"]), len(t), k, transforms_to_array(t[..., :4], t[..., 4:]),
                                    str(asset), None if scale is None else scale.astype(np.float32)))
    return char, motions


def _scaled_lengths(arrays: dict, unit: float) -> dict:
    """A child's result arrays with every length times ``unit``: vertices (N, 3), keypoints and
    default keypoints (K, 3), evaluated vertices (E, N, 3) and the translation part of each clip's
    (F, K, 7) transforms; rotations, weights and per-bone scale factors are unitless and kept."""
    out = dict(arrays)
    for name, value in arrays.items():
        if name in ("vertices", "keypoints", "default_keypoints") or name.endswith("_eval_vertices"):
            out[name] = value * unit
        elif name.endswith("_transforms"):
            out[name] = np.concatenate([value[..., :4], value[..., 4:] * unit], axis=-1)
    return out


def check_output_folder(out_dir: Path) -> None:
    """UserError for an ``out_dir`` holding files (besides the ingest cache) but no ``manifest.json``:
    its shards would be left unlisted and a fresh manifest would claim only this run's rows."""
    if not out_dir.is_dir() or (out_dir / MANIFEST).is_file():
        return
    present = sorted(p.name for p in out_dir.iterdir() if p.name != CACHE)
    if present:
        raise UserError(f"{out_dir}: not empty ({', '.join(present[:5])}{', ...' if len(present) > 5 else ''}) but has "
                        f"no {MANIFEST}; ingest adds to a dataset folder or fills an empty one (restore the "
                        f"manifest, or give another --out)")


def asset_of_row(row_asset: str, assets: set[str]) -> str | None:
    """The asset of ``assets`` a status row belongs to: the row's own path, or for a clip row
    ``<asset>#<clip>`` the asset it starts with (a path may itself hold ``#``); None if neither."""
    if row_asset in assets:
        return row_asset
    cut = row_asset.find("#")
    while cut >= 0:
        if row_asset[:cut] in assets:
            return row_asset[:cut]
        cut = row_asset.find("#", cut + 1)
    return None


def bvh_declared_frames(path: Path) -> int | None:
    """The ``Frames:`` count of a BVH file's MOTION section (None when the file has none)."""
    with open(path, "rb") as f:
        for raw in f:
            line = raw.strip()
            if line.upper().startswith(b"FRAMES:"):
                try:
                    return int(line.split(b":", 1)[1].strip())
                except ValueError:
                    raise ValueError(f"{path}: BVH 'Frames:' line is not a whole number: {line[:60]!r}") from None
    return None


def _blender_problem(a: Path, opts: IngestOptions) -> str | None:
    """Why the asset ``a`` is not handed to Blender (None: it is): missing, unsupported, a glTF
    resource outside its folder (unless allowed), a malformed GLB, a BVH clip over the length bound."""
    if not a.is_file():
        return "file not found"
    if a.suffix.lower() not in SUPPORTED:
        return f"unsupported file type {a.suffix!r}; expected one of {', '.join(SUPPORTED)}"
    try:
        if a.suffix.lower() in (".gltf", ".glb"):
            uris = external_uri_problems(a)  # also refuses a malformed GLB or JSON (one parser with the loader)
            if uris and not opts.allow_external_uris:
                return ("refused: " + "; ".join(uris) + " (resources outside the asset's folder are read only with "
                        "--allow-external-uris)")
        elif a.suffix.lower() == ".bvh" and (declared := bvh_declared_frames(a)) is not None:
            check_clip_frames(declared, f"{a}: BVH 'Frames: {declared}'", opts.max_clip_frames)
        opts.child_options(a)  # a BVH whose HIERARCHY cannot be read for --bvh-scale auto
    except (ValueError, OSError) as exc:
        return str(exc)
    return None


def ingest_assets(paths, out_dir, progress: bool = True, engine=None, **options) -> dict:
    """Ingest ``paths`` into ``out_dir`` (keeping what earlier runs put there); return a summary.

    Args:
        paths: asset files (.glb, .gltf, .fbx, .bvh, .obj, .blend through Blender; .pmx, .pmd, .vmd
            through :mod:`mimicbench.datagen.mmd`) or folders, walked for them (:mod:`.asset_paths`; never ``out_dir``).
        engine: a Ray engine (:mod:`mimicbench.engines`) runs each asset as a task with its worker's
            own Blender (:mod:`.engine_task`); None or a local engine: ``jobs`` Blender processes here.
        options: the fields of :class:`IngestOptions`.

    A character or clip with a NaN or infinite value is not stored: the asset or the clip
    (``<asset>#<clip>``) gets a failed status row.

    Raises:
        ValueError: an option out of range (the message says what is allowed).
        UserError: ``out_dir`` holds files but no manifest (:func:`check_output_folder`).
    """
    from mimicbench.datagen.splits import load_split_file

    opts = IngestOptions(**options)
    opts.check()
    split_map = load_split_file(opts.split_file) if opts.split_file else {}

    def split_for(cid: str) -> str:
        return opts.split or split_map.get(cid) or split_of(cid)

    start = time.perf_counter()
    out_dir = Path(out_dir)
    writer = hold(out_dir)  # noqa: F841 -- one writer at a time, from before the checks; released on return
    check_output_folder(out_dir)
    run = StageRun(STAGE, opts, out_dir, info={"cache_key": "<stem>-<content sha256[:16]>-<options digest[:8]>"})
    cache = out_dir / CACHE
    cache.mkdir(parents=True, exist_ok=True)
    old_chars, old_motions, old_status = (run.earlier_rows(t) for t in ("characters", "motions", "status"))
    taken = {c.character_id: c.source for c in old_chars}
    assets, empty_folders = expand_asset_paths(paths, skip=out_dir)
    from mimicbench.datagen.mmd.ingest import ingest_mmd, split_mmd_paths  # MMD files: no Blender (datagen/mmd)

    assets, mmd_assets = split_mmd_paths(assets)
    statuses: list[StatusRecord] = [
        StatusRecord(f, "ingest", "failed", f"folder holds no asset files (expected {', '.join(FOLDER_SUFFIXES)})", 0.0)
        for f in empty_folders]
    jobs_todo, plan = [], {}
    for a in assets:
        problem = _blender_problem(a, opts)
        if problem:
            statuses.append(StatusRecord(str(a), "ingest", "failed", problem, 0.0))
            continue
        key = cache_key(a, file_sha256(a), opts.child_options(a))
        cid = character_id_for(a, taken)
        taken[cid] = str(a)
        plan[a] = (key, cid)
        if status_of(cache / f"{key}.json") == "ok" and (cache / f"{key}.npz").exists():
            statuses.append(StatusRecord(str(a), "ingest", "skipped", "already ingested", 0.0))
        else:
            jobs_todo.append(a)
    skipped = sum(s.status == "skipped" for s in statuses)
    if engine is not None and engine.name != "local":
        from mimicbench.datagen.ingest.engine_task import TASK_RESOURCES, ingest_task
        from mimicbench.datagen.stage_runner import run_stage

        items = [(str(a), str(cache / f"{plan[a][0]}.npz"), opts.child_options(a), opts.timeout, opts.assets_per_process)
                 for a in jobs_todo]
        returned, task_rows = run_stage(items, ingest_task, "ingest", name_of=lambda it: it[0], progress=progress,
                                        engine=engine, resources=TASK_RESOURCES)
        by_asset = {s.asset: s for s in returned}
        statuses += [by_asset.get(t.asset, t) for t in task_rows]  # a task whose worker died for good: its row
        jobs_todo = []
    workers: Queue = Queue()
    for _ in range(min(opts.jobs, max(1, len(jobs_todo)))):
        workers.put(blender_pool.BlenderWorker(blender_pool.CHILD_MODULE, opts.assets_per_process))

    def job(a: Path) -> StatusRecord:
        w = workers.get()
        try:
            return run_job(w, a, cache / f"{plan[a][0]}.npz", opts.child_options(a), opts.timeout)
        finally:
            workers.put(w)

    try:
        with ThreadPoolExecutor(max_workers=opts.jobs) as pool:
            statuses += tqdm(pool.map(job, jobs_todo), total=len(jobs_todo), desc="ingest", unit="asset",
                             disable=not progress)
    finally:
        while not workers.empty():
            workers.get().stop()
    chars, motions = [], []
    for a, (key, cid) in plan.items():
        if status_of(cache / f"{key}.json") != "ok":
            continue
        c, m = records_from_cache(a, cache, key, cid, split_for(cid), opts.category_map,
                                  opts.bvh_scale_for(a) if a.suffix.lower() == ".bvh" else None, opts.mesh_unit)
        bad = nonfinite_arrays(c, ("vertices", "keypoints", "weight_values"))
        if bad:
            statuses = [s for s in statuses if s.asset != str(a)] + [StatusRecord(  # the asset's own rows
                str(a), "ingest", "failed", f"non-finite values (NaN or inf) in {', '.join(bad)}: not stored", 0.0)]
            continue
        for e in json.loads((cache / f"{key}.json").read_text()).get("clip_errors", []):
            statuses.append(StatusRecord(f"{a}#{e['name']}", "ingest", "failed", f"clip {e['name']!r}: {e['reason']}", 0.0))
        chars.append(c)
        for rec in m:
            if bad := nonfinite_arrays(rec, ("transforms", "scale")):
                statuses.append(StatusRecord(f"{a}#{rec.name}", "ingest", "failed", f"clip {rec.name!r}: non-finite "
                                             f"values (NaN or inf) in {', '.join(bad)}: not stored", 0.0))
            else:
                motions.append(rec)
    mmd = ingest_mmd(mmd_assets, lambda a: category_from_map(a, opts.category_map) or "unknown",
                     scale=float(opts.mmd_unit), progress=progress and bool(mmd_assets), run=run, taken=taken,
                     max_frames=opts.max_clip_frames, split_for=split_for)
    chars, motions, statuses = chars + mmd.characters, motions + mmd.motions, statuses + mmd.statuses
    warnings = []
    for c in chars:
        info = (c.meta or {}).get("ingest") or {}
        h = info.get("skeleton_height_m")
        if h is not None and not PLAUSIBLE_HEIGHT_M[0] <= h <= PLAUSIBLE_HEIGHT_M[1]:
            warnings.append(f"{c.character_id}: skeleton {h:.3g} m tall at {info['bvh_scale']:g} m per file unit "
                            f"({info.get('bvh_unit') or '--bvh-scale'}); if that is not the file's unit, pass "
                            f"--bvh-scale (metres per file unit; CMU conversions use 0.056444)")
        unit = info.get("metres_per_unit")
        extent = float(np.ptp(c.vertices, axis=0).max()) if unit is not None and len(c.vertices) else None
        if extent is not None and not PLAUSIBLE_EXTENT_M[0] <= extent <= PLAUSIBLE_EXTENT_M[1]:
            warnings.append(f"{c.character_id}: {extent:.3g} m across at rest at {unit:g} m per file unit; if the file "
                            f"is authored in another unit, pass --mesh-unit (metres per unit: 0.01 for centimetres)")
    from mimicbench.datagen.roles.attach import carry_labels

    chars = carry_labels(old_chars, chars)  # labels of `datagen roles` survive a re-ingest of the same bones
    new_ids = {c.character_id for c in chars}
    chars = [c for c in old_chars if c.character_id not in new_ids] + chars
    motions = [m for m in old_motions if m.character_id not in new_ids] + motions
    this_run = ({str(a) for a in assets} | {str(a) for a in mmd_assets} | {s.asset for s in mmd.statuses}
                | set(empty_folders))
    statuses = [s for s in old_status if asset_of_row(s.asset, this_run) is None] + statuses
    run.begin()  # until every table below is written
    splits = {c.split for c in chars} | {c.split for c in old_chars}
    run.write_splits("characters", chars, splits)
    run.write_splits("motions", motions, splits)
    run.write_status(statuses, config=None)
    from mimicbench.datagen.ingest.card import write_card

    write_card(out_dir, chars, motions, run.config)
    run.finish()
    if opts.export:
        from mimicbench.datagen.ingest.export import export_dataset

        export_dataset(out_dir, chars, motions, opts.export)
    run_status = [s for s in statuses if asset_of_row(s.asset, this_run) is not None]
    is_clip = [asset_of_row(s.asset, this_run) != s.asset for s in run_status]
    return {"assets": len(assets) + len(mmd_assets), "ingested": sum(s.status == "ok" for s in run_status), "skipped": skipped,
            "failed": sum(s.status == "failed" and not c for s, c in zip(run_status, is_clip)),
            "failed_clips": sum(s.status == "failed" and c for s, c in zip(run_status, is_clip)),
            "characters": len(chars), "motions": len(motions), "seconds": time.perf_counter() - start,
            "statuses": run_status, "character_ids": {str(a): plan[a][1] for a in plan}, "warnings": warnings}
