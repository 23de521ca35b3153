"""Non-finite values (NaN, +-inf) in records and in stored shards: refused at ingest, reported by
``validate``. A NaN in one rotation would otherwise be stored, pass every other check, and make
every metric of every case that uses the clip NaN."""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

# Float columns that hold mesh or animation values, per table (``validate`` checks these).
FINITE_COLUMNS = {
    "characters": ("vertices", "keypoints", "weight_values", "height"),
    "motions": ("fps", "transforms", "scale"),
}


def nonfinite_arrays(record, names) -> list[str]:
    """The attributes of ``record`` among ``names`` whose array holds a NaN or an infinity, each
    as ``name (n values)``; attributes that are None are fine."""
    out = []
    for name in names:
        value = getattr(record, name, None)
        if value is None:
            continue
        arr = np.asarray(value)
        if arr.dtype.kind in "fc":
            n = int(arr.size - np.count_nonzero(np.isfinite(arr)))
            if n:
                out.append(f"{name} ({n} values)")
    return out


def _leaf_values(array) -> pa.Array:
    """The innermost values of a (chunked, possibly nested list) Arrow array, nulls dropped."""
    if isinstance(array, pa.ChunkedArray):
        array = pa.concat_arrays(array.chunks) if array.num_chunks else pa.array([], array.type)
    while pa.types.is_list(array.type) or pa.types.is_large_list(array.type) or pa.types.is_fixed_size_list(array.type):
        array = array.flatten()
    return array.drop_null()


def nonfinite_counts(table: pa.Table, columns) -> dict[str, int]:
    """{column: number of NaN/inf values} for the float columns of ``table`` among ``columns``
    that hold any (others left out)."""
    out = {}
    for name in columns:
        if name not in table.column_names:
            continue
        values = _leaf_values(table.column(name))
        if not pa.types.is_floating(values.type) or not len(values):
            continue
        bad = len(values) - pc.sum(pc.is_finite(values).cast(pa.int64())).as_py()
        if bad:
            out[name] = int(bad)
    return out
