"""Column specifications and the conversion between records and Arrow tables.

A record type is a dataclass whose class attribute ``COLUMNS`` lists :class:`Column` specs in
field order. Array columns hold NumPy arrays in the record and Arrow list columns on disk:

- ``kind="scalar"``: one value of ``dtype`` (``"string"``, ``"bool"``, ``"int32"``, ``"int64"``,
  ``"float32"``, ``"float64"``).
- ``kind="list"``: a 1-D array (n,) stored as ``list<dtype>``.
- ``kind="rows"``: a 2-D array (n, width) stored as ``list<fixed_size_list<dtype, width>>``.
- ``kind="strings"``: a list of n strings stored as ``list<string>``.
- ``kind="json"``: a dict stored as a JSON string.

``reshape`` names the integer fields whose values give the record's array shape (for example
``("num_frames", "num_joints", 7)``); the array is stored flat in its column kind.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import pyarrow as pa

from mimicbench.schemas.version import METADATA_KEY, SCHEMA_VERSION, TABLE_KEY

_ARROW_TYPES = {
    "string": pa.string(),
    "bool": pa.bool_(),
    "int32": pa.int32(),
    "int64": pa.int64(),
    "float32": pa.float32(),
    "float64": pa.float64(),
}


@dataclass(frozen=True)
class Column:
    """One column of a table: its name, kind, element dtype and documentation."""

    name: str
    kind: str
    dtype: str = "string"
    width: int | None = None
    nullable: bool = False
    reshape: tuple | None = None
    doc: str = ""

    def arrow_type(self) -> pa.DataType:
        if self.kind == "json":
            return pa.string()
        base = _ARROW_TYPES[self.dtype]
        if self.kind == "scalar":
            return base
        if self.kind in ("list", "strings"):
            return pa.list_(base)
        if self.kind == "rows":
            return pa.list_(pa.list_(base, self.width))
        raise ValueError(f"column {self.name}: unknown kind {self.kind!r}")

    def numpy_dtype(self):
        return np.dtype({"float32": np.float32, "float64": np.float64, "int32": np.int32,
                         "int64": np.int64, "bool": np.bool_}[self.dtype])


def arrow_schema(columns: Sequence[Column], table: str) -> pa.Schema:
    """The Arrow schema of a table, with the schema version and table name in its metadata."""
    fields = [pa.field(c.name, c.arrow_type(), nullable=c.nullable) for c in columns]
    return pa.schema(fields, metadata={METADATA_KEY: SCHEMA_VERSION.encode(), TABLE_KEY: table.encode()})


def _column_array(col: Column, values: list[Any]) -> pa.Array:
    typ = col.arrow_type()
    if col.kind == "scalar":
        return pa.array(values, type=typ)
    if col.kind == "json":
        return pa.array([None if v is None else json.dumps(v, sort_keys=True) for v in values], type=typ)
    if col.kind == "strings":
        return pa.array([None if v is None else [str(s) for s in v] for v in values], type=typ)
    dt = col.numpy_dtype()
    width = col.width or 1
    flats, lengths, mask = [], [], []
    for v in values:
        if v is None:
            if not col.nullable:
                raise ValueError(f"column {col.name}: got None, expected an array")
            lengths.append(0)
            mask.append(True)
            continue
        a = np.ascontiguousarray(np.asarray(v, dtype=dt)).reshape(-1)
        if a.size % width:
            raise ValueError(f"column {col.name}: expected a multiple of {width} values, got {a.size}")
        flats.append(a)
        lengths.append(a.size // width)
        mask.append(False)
    flat = np.concatenate(flats) if flats else np.zeros(0, dtype=dt)
    offsets = np.zeros(len(lengths) + 1, dtype=np.int64)
    np.cumsum(lengths, out=offsets[1:])
    inner = pa.array(flat, type=_ARROW_TYPES[col.dtype])
    if col.kind == "rows":
        inner = pa.FixedSizeListArray.from_arrays(inner, col.width)
    off32 = pa.array(offsets.astype(np.int32), pa.int32())
    arr = pa.ListArray.from_arrays(off32, inner, mask=pa.array(mask, pa.bool_()) if any(mask) else None)
    return arr.cast(typ)


def records_to_table(records: Sequence[Any], record_type: type, table: str) -> pa.Table:
    """Convert dataclass records of ``record_type`` to an Arrow table with its versioned schema."""
    cols: Sequence[Column] = record_type.COLUMNS
    for r in records:
        if not isinstance(r, record_type):
            raise TypeError(f"expected {record_type.__name__} records, got {type(r).__name__}")
    arrays = [_column_array(c, [getattr(r, c.name) for r in records]) for c in cols]
    return pa.Table.from_arrays(arrays, schema=arrow_schema(cols, table))


def _column_values(col: Column, arr: pa.ChunkedArray) -> list[Any]:
    if col.kind == "scalar":
        return arr.to_pylist()
    if col.kind == "json":
        return [None if v is None else json.loads(v) for v in arr.to_pylist()]
    if col.kind == "strings":
        return arr.to_pylist()
    arr = arr.combine_chunks() if isinstance(arr, pa.ChunkedArray) else arr
    if len(arr) == 0:
        return []
    offsets = np.asarray(arr.offsets)
    values = arr.values
    if col.kind == "rows":
        flat = values.flatten().to_numpy(zero_copy_only=False).astype(col.numpy_dtype(), copy=False)
        flat = flat.reshape(-1, col.width)
    else:
        flat = values.to_numpy(zero_copy_only=False).astype(col.numpy_dtype(), copy=False)
    # ``arr.values`` is the whole child array even when ``arr`` is a slice, and ``arr.offsets``
    # index into it, so no rebasing is needed.
    valid = arr.is_valid().to_numpy(zero_copy_only=False)
    out = []
    for i in range(len(arr)):
        if not valid[i]:
            out.append(None)
            continue
        out.append(np.array(flat[offsets[i]: offsets[i + 1]]))
    return out


def table_to_records(table: pa.Table, record_type: type) -> list[Any]:
    """Convert an Arrow table back into records of ``record_type`` (arrays reshaped)."""
    cols: Sequence[Column] = record_type.COLUMNS
    missing = [c.name for c in cols if c.name not in table.column_names and not c.nullable]
    if missing:
        raise ValueError(f"table: missing columns {missing} for {record_type.__name__}")
    data = {}
    for c in cols:
        if c.name in table.column_names:
            data[c.name] = _column_values(c, table.column(c.name))
        else:
            data[c.name] = [None] * table.num_rows
    records = []
    for i in range(table.num_rows):
        kw = {c.name: data[c.name][i] for c in cols}
        for c in cols:
            if c.reshape and kw[c.name] is not None:
                shape = tuple(kw[s] if isinstance(s, str) else s for s in c.reshape)
                kw[c.name] = kw[c.name].reshape(shape)
        records.append(record_type(**kw))
    return records


def record_field_names(record_type: type) -> list[str]:
    return [f.name for f in dataclasses.fields(record_type)]
