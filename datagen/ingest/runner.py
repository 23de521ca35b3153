"""Ingest assets through Blender, one child process per asset, into a dataset.

Each asset runs ``python -m datagen.ingest.blender_child`` with a timeout; its result is cached
as ``DATASET/.ingest/<stem>.npz`` + ``.json``, so a re-run skips assets already done. A crash, a
timeout or an unreadable file becomes a status row (split ``ingest``) with the reason, and the
other assets go on. At the end the ``characters``/``motions`` tables are rebuilt from every
cached result.
"""
from __future__ import annotations

import fnmatch
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from datagen.splits import split_of
from mimicbench.kinematics import transforms_to_array
from mimicbench.weights import SparseWeights
from schemas.character import CharacterRecord
from schemas.motion import MotionRecord
from schemas.shards import write_records
from schemas.status import StatusRecord
from schemas.validate import validate_dataset

CACHE = ".ingest"


def run_child(asset: Path, cache: Path, timeout: float) -> StatusRecord:
    """Ingest one asset in a child process; return its status row."""
    out = cache / f"{asset.stem}.npz"
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "datagen.ingest.blender_child", str(asset), str(out)],
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return StatusRecord(str(asset), "ingest", "failed", f"timed out after {timeout:g} s", time.perf_counter() - start)
    seconds = time.perf_counter() - start
    result_file = out.with_suffix(".json")
    if not result_file.exists():
        tail = (proc.stderr or proc.stdout or "").strip().splitlines()[-1:] or ["no output"]
        return StatusRecord(str(asset), "ingest", "failed",
                            f"Blender process ended with code {proc.returncode} ({tail[0][:200]})", seconds)
    result = json.loads(result_file.read_text())
    if result["status"] != "ok":
        result_file.unlink()
        return StatusRecord(str(asset), "ingest", "failed", result["reason"], seconds)
    return StatusRecord(str(asset), "ingest", "ok", "", seconds)


def category_for(asset: Path, category_map: dict | None) -> str:
    """Category of an asset: the first glob or name in the map that matches, else ``unknown``."""
    for pattern, category in (category_map or {}).items():
        if fnmatch.fnmatch(asset.name, pattern) or fnmatch.fnmatch(str(asset), pattern) or asset.stem == pattern:
            return category
    return "unknown"


def records_from_cache(asset: Path, cache: Path, category: str) -> tuple[CharacterRecord, list[MotionRecord]]:
    """Character and motion records of one cached child result."""
    meta = json.loads((cache / f"{asset.stem}.json").read_text())
    d = np.load(cache / f"{asset.stem}.npz")
    cid = f"assets/{asset.stem}"
    split = split_of(cid)
    verts = d["vertices"].astype(np.float32)
    k = len(meta["bone_names"])
    if len(verts):
        w = SparseWeights.from_dense(d["weights"])
    else:
        w = SparseWeights(np.zeros((0, 8), np.int32), np.zeros((0, 8), np.float32), k)
    height = float(np.ptp(verts[:, 1])) if len(verts) else None
    char = CharacterRecord(
        character_id=cid, category=category, source=str(asset), split=split, vertices=verts,
        faces=d["faces"].astype(np.int32), keypoints=d["keypoints"].astype(np.float32),
        parents=d["parents"].astype(np.int32), bone_names=meta["bone_names"], weight_indices=w.indices,
        weight_values=w.values, apparel_vertex_mask=np.zeros(len(verts), bool), apparel_bone_mask=np.zeros(k, bool),
        bone_roles=None, skeleton_id=None, height=height,
        meta={"ingest": {"blender": meta.get("blender"), "meshes": meta.get("meshes"), "clips": meta["clips"],
                         "applied_modifiers": meta.get("applied_modifiers", [])}})
    motions = []
    for ci, clip in enumerate(meta["clips"]):
        t = d[f"clip{ci}_transforms"]
        motions.append(MotionRecord(f"{cid}/{clip['name']}", cid, clip["name"], split, float(clip["fps"]), len(t), k,
                                    transforms_to_array(t[..., :4], t[..., 4:]), str(asset)))
    return char, motions


def ingest_assets(paths, out_dir, jobs: int = 1, timeout: float = 300.0, category_map: dict | None = None,
                  export=(), progress: bool = True) -> dict:
    """Ingest assets into ``out_dir``; returns a summary with the status rows.

    Args:
        paths: asset files (.glb, .gltf, .fbx, .bvh, .obj).
        out_dir: dataset folder.
        jobs: child processes at once.
        timeout: seconds per asset before its child is killed.
        category_map: glob or file stem -> category.
        export: ``("obj", "bvh")`` to also write ``out_dir/export/<stem>.obj`` and ``<stem>/<clip>.bvh``.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    cache = out_dir / CACHE
    cache.mkdir(parents=True, exist_ok=True)
    assets = [Path(p).resolve() for p in paths]
    from datagen.mmd.ingest import ingest_mmd, split_mmd_paths  # MMD files: no Blender (datagen/mmd)
    assets, mmd_assets = split_mmd_paths(assets)
    done = [a for a in assets if (cache / f"{a.stem}.json").exists() and (cache / f"{a.stem}.npz").exists()]
    todo = [a for a in assets if a not in done]
    statuses = [StatusRecord(str(a), "ingest", "skipped", "already ingested", 0.0) for a in done]
    bar = tqdm(total=len(todo), desc="ingest", unit="asset", disable=not progress)
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        for status in pool.map(lambda a: run_child(a, cache, timeout), todo):
            statuses.append(status)
            bar.update(1)
    bar.close()
    chars, motions = [], []
    for a in assets:
        if (cache / f"{a.stem}.json").exists():
            c, m = records_from_cache(a, cache, category_for(a, category_map))
            chars.append(c)
            motions.extend(m)
    mmd = ingest_mmd(mmd_assets, lambda a: category_for(a, category_map), progress=progress, out_dir=out_dir)
    chars, motions, statuses = chars + mmd.characters, motions + mmd.motions, statuses + mmd.statuses
    config = {"stage": "ingest", "timeout": timeout, "category_map": category_map or {}}
    for split in sorted({c.split for c in chars}):
        write_records(out_dir, "characters", [c for c in chars if c.split == split], split, rows_per_shard=200, config=config)
        write_records(out_dir, "motions", [m for m in motions if m.split == split], split, rows_per_shard=200, config=config)
    write_records(out_dir, "status", statuses, split="ingest")
    if export:
        from datagen.ingest.export import export_dataset

        export_dataset(out_dir, chars, motions, export)
    problems = validate_dataset(out_dir)
    if problems:
        raise RuntimeError("ingest wrote an invalid dataset:\n" + "\n".join(problems))
    return {"assets": len(assets), "ingested": sum(s.status == "ok" for s in statuses), "skipped": len(done),
            "failed": sum(s.status == "failed" for s in statuses), "characters": len(chars), "motions": len(motions),
            "seconds": time.perf_counter() - start, "statuses": statuses}
