"""Results on disk: ``RESULTS/<method>/<version>/part-*.parquet`` plus ``RESULTS/run.json``.

Each evaluator batch appends one part file, written under a temporary name, fsynced and renamed
when complete (created with the user's umask), so a killed run loses at most the batch in flight
and a re-run computes only the cases without a row. ``run.json`` records the protocols' case
counts, so the leaderboard can tell a missing case from one never asked for.

Part names carry their stored order: ``part-{seq:010d}-r{rank:03d}-{id}.parquet``, where ``seq``
is one more than the largest sequence number in the folder when the part is written. When a case
has several rows (a ``--retry-failed`` re-run), the row of the part with the highest sequence
number wins (then the later row in that part); file modification times play no part, so a copy of
the folder (``cp -r``) reads the same. A part that is empty (0 bytes), unreadable or not of the
results schema is reported (a warning on the ``mimicbench`` logger) and skipped: its cases count
as missing, and a re-run computes them again.
"""
from __future__ import annotations

import json
import logging
import os
import re
import uuid
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from mimicbench.schemas.columns import records_to_table, table_to_records
from mimicbench.schemas.manifest import atomic_write_bytes
from mimicbench.schemas.result import ResultRecord
from mimicbench.schemas.tables import schema_of

RUN_FILE = "run.json"
PART_RE = re.compile(r"^part-(?P<seq>\d{10})-r(?P<rank>\d{3})-(?P<id>[0-9a-f]{12})\.parquet$")

log = logging.getLogger("mimicbench")
_reported: set[tuple] = set()  # parts already reported as skipped (path, size, mtime)


def method_dir(results: str | os.PathLike, method: str, version: str) -> Path:
    return Path(results) / method / version


def part_files(folder: Path) -> list[Path]:
    """The folder's result parts in stored order (sequence number, then rank, then name).

    A ``part-*.parquet`` whose name does not follow :data:`PART_RE` is reported and left out.
    """
    parts = []
    for p in Path(folder).glob("part-*.parquet"):
        m = PART_RE.match(p.name)
        if m is None:
            _report(p, "its name is not part-<10-digit sequence>-r<rank>-<id>.parquet")
            continue
        parts.append((int(m["seq"]), int(m["rank"]), p.name, p))
    return [p for *_, p in sorted(parts)]


def next_sequence(folder: Path) -> int:
    """One more than the largest sequence number among the folder's parts (1 when none)."""
    seqs = [int(m["seq"]) for p in Path(folder).glob("part-*.parquet") if (m := PART_RE.match(p.name))]
    return max(seqs, default=0) + 1


def append_results(folder: Path, records: list[ResultRecord], rank: int = 0) -> Path | None:
    """Write records as a new part file in ``folder`` (atomic, fsynced); returns its path."""
    if not records:
        return None
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    table = records_to_table(records, ResultRecord, "results")
    final = folder / f"part-{next_sequence(folder):010d}-r{rank:03d}-{uuid.uuid4().hex[:12]}.parquet"
    buf = pa.BufferOutputStream()
    pq.write_table(table, buf)
    atomic_write_bytes(final, buf.getvalue().to_pybytes())  # fsynced, then renamed; umask mode
    return final


def _report(path: Path, reason: str) -> None:
    try:
        st = path.stat()
        key = (str(path), st.st_size, st.st_mtime_ns)
    except OSError:
        key = (str(path), None, None)
    if key not in _reported:
        _reported.add(key)
        log.warning("%s: skipped (%s); its cases count as missing and a re-run computes them", path, reason)


def _read_part(path: Path) -> pa.Table | None:
    """The part's rows in the results schema, or None (reported) when it cannot be used."""
    try:
        if path.stat().st_size == 0:
            _report(path, "empty file, 0 bytes")
            return None
        table, schema = pq.read_table(path), schema_of("results")
        if set(table.column_names) <= set(schema.names):  # a part written before a nullable column existed
            for f in schema:
                if f.name not in table.column_names and f.nullable:
                    table = table.append_column(f.name, pa.nulls(table.num_rows, f.type))
            table = table.select([n for n in schema.names if n in table.column_names])
        return table.cast(schema)
    except Exception as exc:  # pyarrow raises several types for damaged files
        _report(path, f"not a readable result part: {type(exc).__name__}: {exc}")
        return None


def read_results(folder: Path) -> pa.Table:
    """All result rows of one method version; when a case appears twice, the row stored last wins
    (see the module docstring). Unusable parts are reported and skipped.

    A row whose ``method``/``method_version`` is not the folder's (``<method>/<version>``: rows
    copied from another method) never replaces one of the folder's own rows; it is kept only for a
    case the folder has no own row for, so the leaderboard can show it as refused
    (:mod:`mimicbench.benchmark.result_checks`)."""
    folder = Path(folder)
    tables = [t for t in (_read_part(p) for p in part_files(folder)) if t is not None]
    if not tables:
        return schema_of("results").empty_table()
    table = pa.concat_tables(tables)
    ids = table.column("case_id").to_pylist()
    own = [m == folder.parent.name and v == folder.name
           for m, v in zip(table.column("method").to_pylist(), table.column("method_version").to_pylist())]
    last: dict = {}
    for i, (cid, mine) in enumerate(zip(ids, own)):
        if mine or cid not in last or not own[last[cid]]:
            last[cid] = i
    return table.take(sorted(last.values()))


def read_result_records(folder: Path) -> list[ResultRecord]:
    return table_to_records(read_results(folder), ResultRecord)


def done_case_ids(folder: Path, include_failed: bool = True) -> set[str]:
    """Case IDs that already have a row (``ok``, and ``failed`` unless include_failed is False)."""
    folder = Path(folder)
    t = read_results(folder)
    ids, status = t.column("case_id").to_pylist(), t.column("status").to_pylist()
    own = [m == folder.parent.name and v == folder.name
           for m, v in zip(t.column("method").to_pylist(), t.column("method_version").to_pylist())]
    return {c for c, s, mine in zip(ids, status, own) if mine and (include_failed or s == "ok")}


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
