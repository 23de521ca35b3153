"""The resample stage over a dataset: ``mimicbench datagen resample IN OUT``."""
from __future__ import annotations

import json
import shutil
import time
from functools import partial
from pathlib import Path

import numpy as np

from datagen.resample.character import resample_character
from datagen.stage_runner import run_stage, summarize_statuses
from schemas.manifest import load_manifest, save_manifest
from schemas.shards import has_table, read_records, splits_of, write_records
from schemas.status import StatusRecord
from schemas.validate import validate_dataset


def _one(item, faces, backend):
    record, motions = item
    return resample_character(record, motions, faces, backend)


def _copy_table(src: Path, dst: Path, table: str) -> None:
    """Copy a table's shards and manifest entries unchanged."""
    m_src, m_dst = load_manifest(src), load_manifest(dst)
    info = m_src["tables"].get(table)
    if not info:
        return
    for shard in info["shards"]:
        (dst / shard["path"]).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src / shard["path"], dst / shard["path"])
    m_dst["tables"][table] = json.loads(json.dumps(info))
    if table in m_src.get("configs", {}):
        m_dst.setdefault("configs", {})[table] = m_src["configs"][table]
    save_manifest(dst, m_dst)


def resample_dataset(in_dir, out_dir, faces: int = 5000, backend: str = "fast", jobs: int = 1,
                     progress: bool = True) -> dict:
    """Resample every character of ``in_dir`` into ``out_dir`` (a re-run keeps finished ones).

    Characters that fail get a status row (split ``resample``) with the reason and are left out;
    skeleton-only characters (no mesh) are copied as they are. The motions table (and pairs, if
    any) are copied unchanged.

    Returns:
        Summary: counts, failures, mean Hausdorff and transfer error (% of height), seconds.
    """
    start = time.perf_counter()
    in_dir, out_dir = Path(in_dir), Path(out_dir)
    if in_dir.resolve() == out_dir.resolve():
        raise ValueError("resample: IN_DATASET and OUT_DATASET must differ")
    out_dir.mkdir(parents=True, exist_ok=True)
    records = read_records(in_dir, "characters")
    done = {}
    if has_table(out_dir, "characters"):
        done = {r.character_id: r for r in read_records(out_dir, "characters")
                if (r.meta or {}).get("resample", {}).get("faces_out") is not None or len(r.faces) == 0}
    motions: dict[str, list] = {}
    if has_table(in_dir, "motions"):
        for m in read_records(in_dir, "motions"):
            motions.setdefault(m.character_id, []).append(m)
    todo = [r for r in records if r.character_id not in done and len(r.faces) > 0]
    results, statuses = run_stage([(r, motions.get(r.character_id, [])) for r in todo],
                                  partial(_one, faces=faces, backend=backend), "resample",
                                  name_of=lambda item: item[0].character_id, jobs=jobs, progress=progress)
    by_id = dict(done)
    by_id.update({r.character_id: r for r in results})
    by_id.update({r.character_id: r for r in records if len(r.faces) == 0})
    config = {"stage": "resample", "faces": faces, "backend": backend, "source": str(in_dir)}
    for split in splits_of(in_dir, "characters"):
        rows = [by_id[r.character_id] for r in records if r.split == split and r.character_id in by_id]
        write_records(out_dir, "characters", rows, split=split, rows_per_shard=500, config=config)
    old = read_records(out_dir, "status", "resample") if has_table(out_dir, "status", "resample") else []
    kept = [s for s in old if s.asset not in {t.asset for t in statuses}]
    skipped = [StatusRecord(cid, "resample", "skipped", "already resampled", 0.0) for cid in done]
    write_records(out_dir, "status", kept + statuses + skipped if not kept else kept + statuses, split="resample")
    for table in ("motions", "pairs"):
        _copy_table(in_dir, out_dir, table)
    problems = validate_dataset(out_dir)
    if problems:
        raise RuntimeError("resample wrote an invalid dataset:\n" + "\n".join(problems))
    q = [r.meta["resample"] for r in by_id.values() if (r.meta or {}).get("resample")]
    summary = {
        "characters": len(by_id), "resampled": len(results), "already_done": len(done),
        "failed": sum(s.status == "failed" for s in statuses),
        "hausdorff_pct_mean": float(np.mean([x["hausdorff_pct"] for x in q])) if q else None,
        "transfer_error_pct_mean": float(np.mean([x["transfer_error_pct"] for x in q])) if q else None,
        "seconds": time.perf_counter() - start, "statuses": statuses,
    }
    if progress:
        print(summarize_statuses(statuses))
    return summary
