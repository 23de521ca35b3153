"""Check a dataset folder against its manifest and the schema: ``mimicbench validate DIR``."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.finite import FINITE_COLUMNS, nonfinite_counts
from mimicbench.schemas.fingerprint import stale_inputs
from mimicbench.schemas.integrity import entry_path
from mimicbench.schemas.manifest import MANIFEST, incomplete_reason, is_complete, load_manifest, sha256_of
from mimicbench.schemas.shards import SHARD_RE, check_schema
from mimicbench.schemas.tables import RECORD_TYPES, schema_of


UNIQUE_IDS = {"characters": "character_id", "motions": "motion_id"}  # one row per ID, across splits


def parents_problem(parents) -> str | None:
    """Why ``parents`` (K,) int is not a skeleton in the format's order (``-1 <= parents[k] < k``: roots
    first, every joint after its parent, so no cycle), or None when it is."""
    parents = np.asarray(parents).reshape(-1)
    bad = np.flatnonzero((parents < -1) | (parents >= np.arange(len(parents))))
    if len(bad) == 0:
        return None
    k = int(bad[0])
    return (f"parents[{k}] = {int(parents[k])} is not below {k} ({len(bad)} joint(s) out of order; the format "
            f"requires -1 <= parents[k] < k, a skeleton without cycles)")


def _row_arrays(column: pa.ChunkedArray, width: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A list column as (offsets (R+1,), flat values (N,) or (N, width) for a list of fixed-size lists)."""
    array = column.combine_chunks()
    offsets = array.offsets.to_numpy(zero_copy_only=False)
    values = array.values.flatten() if width else array.values
    flat = values.to_numpy(zero_copy_only=False)
    start = offsets[0] * (width or 1)
    offsets = offsets - offsets[0]
    flat = flat[start:start + offsets[-1] * (width or 1)]
    return offsets, flat.reshape(-1, width) if width else flat


def skeleton_and_height_problems(path) -> list[tuple[str, str, str]]:
    """``(character_id, "parents" or "height", why)`` per problem of a characters shard: a skeleton out
    of the format's order (:func:`parents_problem`), a rest mesh with no height (Y extent 0 or not
    finite: every score and the resample's quality divide by it). Reads only the ``character_id``,
    ``parents`` and ``vertices`` columns."""
    table = pq.read_table(path, columns=["character_id", "parents", "vertices"])
    ids = table.column("character_id").to_pylist()
    p_off, parents = _row_arrays(table.column("parents"))
    v_off, verts = _row_arrays(table.column("vertices"), 3)
    problems = []
    for i, cid in enumerate(ids):
        why = parents_problem(parents[p_off[i]:p_off[i + 1]])
        if why:
            problems.append((cid, "parents", why))
        y = verts[v_off[i]:v_off[i + 1], 1]
        extent = float(y.max() - y.min()) if len(y) else None
        if extent is not None and not (np.isfinite(extent) and extent > 0):
            problems.append((cid, "height", f"its rest mesh has no height (Y extent {extent:g}): every score "
                                            f"divides by it"))
    return problems


def validate_dataset(root, values: bool = False) -> list[str]:
    """Problems found in a dataset folder, each naming the file and why; empty when valid.

    Checks: manifest present and parseable with a known schema version; the dataset marked
    complete (not left half-written by a killed stage); every listed shard path is
    ``{table}/{split}-{i}-of-{n}.parquet`` inside the folder (no ``..``, absolute path or symlink
    out), exists, has the recorded size and sha256, reads as Parquet with the recorded row count,
    carries a compatible schema version and the contract's column types; no shard file on disk
    is unlisted; with ``values`` (``mimicbench validate`` asks for it), no NaN or infinite mesh or
    animation value (:data:`mimicbench.schemas.finite.FINITE_COLUMNS`; this decodes those columns, several
    times the cost of the checksums, so the stages' own end-of-run checks leave it out: ingest
    checks every row it adds on the way in);
    with ``values``, no character whose ``parents`` break the format's order (a cycle) or whose rest
    mesh has no height (:func:`skeleton_and_height_problems`);
    no character or motion ID held by two rows (:data:`UNIQUE_IDS`); a table derived from other tables of the same dataset (pairs from characters)
    still matches the fingerprints they had when it was made.
    """
    root = Path(root)
    problems: list[str] = []
    mpath = root / MANIFEST
    if not root.is_dir():
        return [f"{root}: not a folder"]
    try:
        manifest = load_manifest(root)
    except DatasetError as exc:
        return [str(exc)]
    if not is_complete(manifest):
        problems.append(incomplete_reason(root, manifest))
    listed = set()
    ids: dict[str, dict[str, int]] = {}
    for table, info in sorted(manifest.get("tables", {}).items()):
        if table not in RECORD_TYPES:
            problems.append(f"{mpath}: unknown table {table!r}")
            continue
        expected = schema_of(table)
        for entry in info.get("shards", []):
            rel = entry.get("path")
            try:
                path = entry_path(root, rel)
            except DatasetError as exc:
                problems.append(str(exc))
                continue
            parts = Path(rel).parts
            if len(parts) != 2 or parts[0] != table or not SHARD_RE.match(parts[1]):
                problems.append(f"{mpath}: shard path {rel!r} of table {table!r}: expected "
                                f"'{table}/{{split}}-{{i:05d}}-of-{{n:05d}}.parquet'")
                continue
            listed.add(path.resolve())
            if not path.is_file():
                problems.append(f"{path}: missing (listed in manifest.json)")
                continue
            size = path.stat().st_size
            if entry.get("bytes") is not None and size != entry["bytes"]:
                problems.append(f"{path}: {size} bytes, manifest says {entry['bytes']}: the file changed or is truncated")
            digest = sha256_of(path)
            if digest != entry.get("sha256"):
                problems.append(f"{path}: checksum mismatch (sha256 {digest[:12]}..., manifest says "
                                f"{str(entry.get('sha256'))[:12]}...): the file changed or is truncated")
            try:
                meta = pq.read_metadata(path)
                schema = pq.read_schema(path)
            except Exception as exc:
                problems.append(f"{path}: not a readable Parquet file ({exc})")
                continue
            try:
                check_schema(path, schema, expected)
            except DatasetError as exc:
                problems.append(str(exc))
            if meta.num_rows != entry.get("rows"):
                problems.append(f"{path}: {meta.num_rows} rows, manifest says {entry.get('rows')}")
            id_column = UNIQUE_IDS.get(table)
            if id_column in schema.names:
                try:
                    counts = ids.setdefault(table, {})
                    for value in pq.read_table(path, columns=[id_column]).column(id_column).to_pylist():
                        counts[value] = counts.get(value, 0) + 1
                except Exception as exc:
                    problems.append(f"{path}: column {id_column!r} unreadable ({exc})")
            if values and table == "characters" and {"parents", "vertices"} <= set(schema.names):
                try:
                    problems += [f"{path}: character {cid}: {why}"
                                 for cid, _, why in skeleton_and_height_problems(path)]
                except Exception as exc:
                    problems.append(f"{path}: columns parents, vertices unreadable ({exc})")
            columns = [c for c in FINITE_COLUMNS.get(table, ()) if c in schema.names] if values else []
            if columns:
                try:
                    bad = {}
                    for batch in pq.ParquetFile(path).iter_batches(columns=columns):  # one row group's memory
                        for column, n in nonfinite_counts(pa.Table.from_batches([batch]), columns).items():
                            bad[column] = bad.get(column, 0) + n
                except Exception as exc:
                    problems.append(f"{path}: columns {', '.join(columns)} unreadable ({exc})")
                    bad = {}
                for column, n in sorted(bad.items()):
                    problems.append(f"{path}: column {column!r} holds {n} NaN or infinite values")
        stale = stale_inputs(root, manifest, table)
        if stale:
            problems.append(stale)
        listed_rows = sum(e.get("rows", 0) for e in info.get("shards", []))
        if info.get("rows") is not None and info["rows"] != listed_rows:
            problems.append(f"{mpath}: table {table!r} says {info['rows']} rows, its shards {listed_rows}")
    for table, counts in sorted(ids.items()):
        repeated = sorted(k for k, n in counts.items() if n > 1)
        if repeated:
            problems.append(f"{root / table}: {len(repeated)} {UNIQUE_IDS[table]} values held by more than one row "
                            f"({', '.join(map(str, repeated[:5]))}{', ...' if len(repeated) > 5 else ''})")
    for table in RECORD_TYPES:
        folder = root / table
        if not folder.is_dir():
            continue
        for f in sorted(folder.glob("*.parquet")):
            if SHARD_RE.match(f.name) and f.resolve() not in listed:
                problems.append(f"{f}: shard on disk but not listed in manifest.json")
    return problems
