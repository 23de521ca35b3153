"""Results on disk: ``RESULTS/<method>/<version>/part-*.parquet`` plus ``RESULTS/run.json``.

Each evaluator batch appends one part file, written under a temporary name and renamed when
complete, so a killed run loses at most the batch in flight and a re-run computes only the cases
without a row. ``run.json`` records the protocols' case counts, so the leaderboard can tell a
missing case from one never asked for.
"""
from __future__ import annotations

import json
import os
import tempfile
import uuid
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from schemas.columns import records_to_table, table_to_records
from schemas.manifest import atomic_write_bytes
from schemas.result import ResultRecord
from schemas.tables import schema_of

RUN_FILE = "run.json"


def method_dir(results: str | os.PathLike, method: str, version: str) -> Path:
    return Path(results) / method / version


def append_results(folder: Path, records: list[ResultRecord], rank: int = 0) -> Path | None:
    """Write records as a new part file in ``folder`` (atomic); returns its path."""
    if not records:
        return None
    folder.mkdir(parents=True, exist_ok=True)
    table = records_to_table(records, ResultRecord, "results")
    final = folder / f"part-r{rank:03d}-{uuid.uuid4().hex[:12]}.parquet"
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, final)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return final


def read_results(folder: Path) -> pa.Table:
    """All result rows of one method version; the last row wins when a case appears twice."""
    parts = sorted(Path(folder).glob("part-*.parquet"), key=lambda p: p.stat().st_mtime_ns)
    if not parts:
        return schema_of("results").empty_table()
    table = pa.concat_tables([pq.read_table(p).cast(schema_of("results")) for p in parts])
    ids = table.column("case_id").to_pylist()
    last = {cid: i for i, cid in enumerate(ids)}
    return table.take(sorted(last.values()))


def read_result_records(folder: Path) -> list[ResultRecord]:
    return table_to_records(read_results(folder), ResultRecord)


def done_case_ids(folder: Path, include_failed: bool = True) -> set[str]:
    """Case IDs that already have a row (``ok``, and ``failed`` unless include_failed is False)."""
    t = read_results(folder)
    ids, status = t.column("case_id").to_pylist(), t.column("status").to_pylist()
    return {c for c, s in zip(ids, status) if include_failed or s == "ok"}


def write_run_info(results, info: dict) -> None:
    """Merge ``info`` into ``RESULTS/run.json`` (protocol case counts, dataset, methods)."""
    path = Path(results) / RUN_FILE
    current = json.loads(path.read_text()) if path.exists() else {}
    for key, value in info.items():
        if isinstance(value, dict) and isinstance(current.get(key), dict):
            current[key].update(value)
        else:
            current[key] = value
    atomic_write_bytes(path, (json.dumps(current, indent=2, sort_keys=True) + "\n").encode())


def read_run_info(results) -> dict:
    path = Path(results) / RUN_FILE
    return json.loads(path.read_text()) if path.exists() else {}


def method_versions(results) -> list[tuple[str, str]]:
    """Every (method, version) folder holding result parts."""
    out = []
    for mdir in sorted(p for p in Path(results).iterdir() if p.is_dir()):
        for vdir in sorted(p for p in mdir.iterdir() if p.is_dir()):
            if any(vdir.glob("part-*.parquet")):
                out.append((mdir.name, vdir.name))
    return out
