"""Ingest assets into a dataset, additively: Blender children (:mod:`.blender_pool`) for glTF, FBX,
BVH, OBJ and .blend, :mod:`mimicbench.datagen.mmd` for MMD files. Each child result is cached in
``DATASET/.ingest`` under a key of content hash and options (:mod:`.identity`), so a re-run skips
assets already done; every failure is a status row (split ``ingest``). This run's assets replace
only their own rows (by character ID).
"""
from __future__ import annotations

import fnmatch
import glob
import json
from pathlib import Path

import numpy as np

from mimicbench.datagen.ingest.asset_paths import expand_asset_paths
from mimicbench.datagen.ingest.blender_engine import BlenderThreads
from mimicbench.datagen.ingest.bvh_units import PLAUSIBLE_HEIGHT_M
from mimicbench.datagen.ingest.card import write_card
from mimicbench.datagen.ingest.category import infer_category
from mimicbench.datagen.ingest.clip_length import check_clip_frames
from mimicbench.datagen.ingest.engine_task import BLENDER, TASK_RESOURCES
from mimicbench.datagen.ingest.identity import cache_key, character_id_for, file_sha256, skeleton_id
from mimicbench.datagen.ingest.job import status_of
from mimicbench.datagen.ingest.loaders import BLENDER_SUFFIXES, WALKED_SUFFIXES, ingest_item, loader_for
from mimicbench.datagen.ingest.params import EXPORT_FORMATS, IngestParams  # noqa: F401
from mimicbench.datagen.ingest.uris import external_uri_problems
from mimicbench.datagen.mmd.ingest import MMDIngest, model_items, write_physics
from mimicbench.datagen.mmd.loaders import MMD_MODEL
from mimicbench.datagen.roles.attach import carry_labels
from mimicbench.datagen.splits import load_split_file, split_of
from mimicbench.datagen.stage_runner import Stage, StagePlan, StageRun, drive
from mimicbench.runtime.summary import StageSummary
from mimicbench.geometry.kinematics import transforms_to_array
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.runtime.errors import UserError
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.finite import nonfinite_arrays
from mimicbench.schemas.manifest import MANIFEST
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.status import StatusRecord
from mimicbench.schemas.weights import SparseWeights

CACHE = ".ingest"
SUPPORTED = BLENDER_SUFFIXES
PLAUSIBLE_EXTENT_M = (0.05, 30.0)  # a meshed character's largest rest extent outside this: warn (--mesh-unit)


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


def _blender_problem(a: Path, opts: IngestParams) -> str | None:
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


class IngestPlan(StagePlan):
    """The assets of this run as items, one per file, each read by its format's loader
    (:data:`.loaders.LOADERS`): a Blender format into the cache ``OUT/.ingest`` (an asset whose
    cached result matches its content and options is reused), an MMD model here. :meth:`write`
    merges them with the rows earlier runs put in OUT, by character ID."""

    status_config = None

    def __init__(self, run: StageRun):
        super().__init__(run.stage)
        opts, out_dir = run.params, run.out_dir
        check_output_folder(out_dir)
        self.run, self.opts, self.cache = run, opts, out_dir / CACHE
        self.categories = opts.categories()
        split_map = load_split_file(opts.split_file) if opts.split_file else {}
        self.split_for = lambda cid: opts.split or split_map.get(cid) or split_of(cid)
        self.old = {t: run.earlier_rows(t) for t in ("characters", "motions", "status")}
        taken = {c.character_id: c.source for c in self.old["characters"]}
        paths = []
        for pattern in opts.paths:
            matches = sorted(glob.glob(pattern))
            paths.extend(matches or [pattern])
        if opts.motions:  # MMD motions for every model (datagen/mmd/ingest.py)
            paths.extend(str(p) for p in sorted(Path(opts.motions).glob("*.vmd")))
        assets, empty_folders = expand_asset_paths(paths, skip=out_dir)
        # MMD files are read here; every other path goes the Blender way, which names an unknown suffix
        self.mmd_assets = [a for a in assets if loader_for(a) is not None and not loader_for(a).in_blender]
        self.assets = [a for a in assets if a not in set(self.mmd_assets)]
        self.empty_folders = empty_folders
        self.statuses = [StatusRecord(f, "ingest", "failed", f"folder holds no asset files (expected "
                                      f"{', '.join(WALKED_SUFFIXES)})", 0.0) for f in empty_folders]
        self.plan: dict[Path, tuple[str, str]] = {}  # Blender asset -> (cache key, character ID)
        todo = []
        for a in self.assets:
            problem = _blender_problem(a, opts)
            if problem:
                self.statuses.append(StatusRecord(str(a), "ingest", "failed", problem, 0.0))
                continue
            key = cache_key(a, file_sha256(a), opts.child_options(a))
            cid = character_id_for(a, taken)
            taken[cid] = str(a)
            self.plan[a] = (key, cid)
            if status_of(self.cache / f"{key}.json") == "ok" and (self.cache / f"{key}.npz").exists():
                self.reused.append(StatusRecord(str(a), "ingest", "skipped", "already ingested", 0.0))
            else:
                todo.append(a)
        self.items = [(BLENDER.name, (str(a), str(self.cache / f"{self.plan[a][0]}.npz"), opts.child_options(a),
                                      opts.timeout, opts.assets_per_process)) for a in todo]
        mmd_items, lone = model_items(self.mmd_assets, lambda a: category_from_map(a, self.categories) or "unknown",
                                      scale=float(opts.mmd_unit), taken=taken, max_frames=opts.max_clip_frames,
                                      split_for=self.split_for)
        self.items += [(MMD_MODEL.name, item) for item in mmd_items]
        self.lone_motions = lone
        self.returned: dict[str, object] = {}  # asset -> what its loader returned

    def start(self, run) -> None:
        self.cache.mkdir(parents=True, exist_ok=True)

    def function(self):
        return ingest_item

    def name_of(self, item) -> str:
        return item[1][0]

    def engine(self, engine):
        if engine.name == "local":
            return BlenderThreads(self.opts.jobs, self.opts.assets_per_process)
        self.resources = TASK_RESOURCES
        return engine

    def done(self, run, item, ok, result) -> None:
        if ok:
            self.returned[item[1][0]] = result

    def nothing_made(self, statuses) -> bool:
        return False  # additive: a run whose every asset failed still records why

    def write(self, run, statuses):
        opts, cache = self.opts, self.cache
        mmd = MMDIngest()
        rows = []
        for s in statuses:  # a loader's own rows stand for the driver's row of its item
            got = self.returned.get(s.asset)
            if isinstance(got, MMDIngest):
                for name in ("characters", "motions", "rigid_bodies", "joints", "statuses"):
                    getattr(mmd, name).extend(getattr(got, name))
            else:
                rows.append(got if got is not None else s)
        statuses = rows + self.reused
        chars, motions = [], []
        for a, (key, cid) in self.plan.items():
            if status_of(cache / f"{key}.json") != "ok":
                continue
            c, m = records_from_cache(a, cache, key, cid, self.split_for(cid), self.categories,
                                      opts.bvh_scale_for(a) if a.suffix.lower() == ".bvh" else None, opts.mesh_unit)
            bad = nonfinite_arrays(c, ("vertices", "keypoints", "weight_values"))
            if bad:
                statuses = [s for s in statuses if s.asset != str(a)] + [StatusRecord(  # the asset's own rows
                    str(a), "ingest", "failed", f"non-finite values (NaN or inf) in {', '.join(bad)}: not stored", 0.0)]
                continue
            for e in json.loads((cache / f"{key}.json").read_text()).get("clip_errors", []):
                statuses.append(StatusRecord(f"{a}#{e['name']}", "ingest", "failed",
                                             f"clip {e['name']!r}: {e['reason']}", 0.0))
            chars.append(c)
            for rec in m:
                if bad := nonfinite_arrays(rec, ("transforms", "scale")):
                    statuses.append(StatusRecord(f"{a}#{rec.name}", "ingest", "failed", f"clip {rec.name!r}: "
                                                 f"non-finite values (NaN or inf) in {', '.join(bad)}: not stored", 0.0))
                else:
                    motions.append(rec)
        mmd.statuses += self.lone_motions
        chars, motions, statuses = chars + mmd.characters, motions + mmd.motions, statuses + mmd.statuses
        warnings = _unit_warnings(chars)
        old_chars = self.old["characters"]
        chars = carry_labels(old_chars, chars)  # labels of `datagen roles` survive a re-ingest of the same bones
        new_ids = {c.character_id for c in chars}
        chars = [c for c in old_chars if c.character_id not in new_ids] + chars
        motions = [m for m in self.old["motions"] if m.character_id not in new_ids] + motions
        this_run = ({str(a) for a in self.assets} | {str(a) for a in self.mmd_assets} | {s.asset for s in mmd.statuses}
                    | set(self.empty_folders))
        statuses = [s for s in self.old["status"] if asset_of_row(s.asset, this_run) is None] + statuses
        splits = {c.split for c in chars} | {c.split for c in old_chars}
        run.write_splits("characters", chars, splits)
        run.write_splits("motions", motions, splits)
        if mmd.characters:
            write_physics(run, mmd)
        write_card(run.out_dir, chars, motions, run.config)
        self.chars, self.motions = chars, motions
        run_status = [s for s in statuses if asset_of_row(s.asset, this_run) is not None]
        is_clip = [asset_of_row(s.asset, this_run) != s.asset for s in run_status]
        self.reported = run_status
        self.failed = sum(s.status == "failed" and not c for s, c in zip(run_status, is_clip))
        return statuses, {
            "assets": len(self.assets) + len(self.mmd_assets), "ingested": sum(s.status == "ok" for s in run_status),
            "skipped": len(self.reused), "failed": self.failed,
            "failed_clips": sum(s.status == "failed" and c for s, c in zip(run_status, is_clip)),
            "characters": len(chars), "motions": len(motions),
            "character_ids": {str(a): self.plan[a][1] for a in self.plan}, "warnings": warnings}

    def after(self, run) -> None:
        if self.opts.export:
            from mimicbench.datagen.ingest.export import export_dataset

            export_dataset(run.out_dir, self.chars, self.motions, self.opts.export)

    def counts(self, statuses) -> tuple[int, int]:
        return len(self.chars), self.failed


def _unit_warnings(chars: list) -> list[str]:
    """A line for each character whose size suggests a wrong ``--bvh-scale`` or ``--mesh-unit``."""
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
    return warnings


STAGE = Stage("ingest", IngestParams, inputs=(), item=ingest_item, outputs=("characters", "motions", "status"),
              out_name="--out folder", plan=IngestPlan, out_key="out", check=IngestParams.check,
              info=lambda params: {"cache_key": "<stem>-<content sha256[:16]>-<options digest[:8]>"}, what="asset",
              command=("datagen", "ingest"), function="mimicbench.datagen.ingest.runner:run_command",
              step_reads=(("paths", None),), step_writes=("characters", "motions"))


def ingest_assets(paths, out_dir, progress: bool = True, engine=None, **options) -> dict:
    """Ingest ``paths`` into ``out_dir`` (keeping what earlier runs put there): :func:`drive` with
    :data:`STAGE`; return the summary's details with ``seconds`` and ``statuses`` (this run's rows).

    Args:
        paths: asset files (.glb, .gltf, .fbx, .bvh, .obj, .blend through Blender; .pmx, .pmd, .vmd
            through :mod:`mimicbench.datagen.mmd`) or folders, walked for them (:mod:`.asset_paths`; never
            ``out_dir``); glob patterns are expanded.
        engine: a Ray engine (:mod:`mimicbench.engines`) runs each asset as a task with its worker's
            own Blender (:mod:`.engine_task`); None or a local engine: ``jobs`` Blender processes here.
        options: the other fields of :class:`.params.IngestParams` (``category_map`` may be the mapping itself).

    A character or clip with a NaN or infinite value is not stored: the asset or the clip
    (``<asset>#<clip>``) gets a failed status row.

    Raises:
        ValueError: an option out of range (the message says what is allowed).
        UserError: ``out_dir`` holds files but no manifest (:func:`check_output_folder`).
    """
    params = IngestParams(paths=tuple(str(p) for p in paths), out=str(out_dir), quiet=not progress, **options)
    s = drive(STAGE, params, engine=engine)
    return {**s.details, "seconds": s.seconds, "statuses": list(s.statuses)}


def run_command(params: IngestParams) -> StageSummary:
    """``mimicbench datagen ingest``: the stage on ``params`` and its report (what the command line and a
    pipeline step call)."""
    from mimicbench.datagen.stage_runner import summarize_statuses
    from mimicbench.schemas.dataset import Dataset

    s = drive(STAGE, params)
    d = s.details
    if params.quiet:
        print(summarize_statuses([x for x in s.statuses if x.status != "skipped"]))
    for w in d["warnings"]:
        print(f"warning: {w}")
    print(f"{d['characters']} characters and {d['motions']} clips in {params.out} ({d['skipped']} already done, "
          f"{d['failed']} failed, {d['failed_clips']} clips unreadable) in {s.seconds:.1f} s")
    if not Dataset.of(params.out).has_table("characters"):  # every asset failed: nothing to label or report
        return s
    if params.roles:
        from mimicbench.datagen.roles.attach import attach_roles, print_warnings, summary_lines

        labels = attach_roles(params.out, params.roles)
        print_warnings(labels)
        print("\n".join(summary_lines(labels)))
    from mimicbench.datagen.roles.categories import inferred_lines

    for line in inferred_lines(params.out):
        print(line)
    return s
