"""The tables a dataset folder can hold, by name."""
from __future__ import annotations

from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.columns import arrow_schema
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.pair import PairRecord
from mimicbench.schemas.result import ResultRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord
from mimicbench.schemas.status import StatusRecord

RECORD_TYPES = {
    "characters": CharacterRecord,
    "motions": MotionRecord,
    "pairs": PairRecord,
    "cases": CaseRecord,
    "status": StatusRecord,
    "results": ResultRecord,
    "rigid_bodies": RigidBodyRecord,
    "joints": JointRecord,
}

# Parquet encodings of single columns (leaf paths) instead of the default dictionary encoding.
# pairs.m_sink: Sinkhorn probabilities, nearly all distinct, so the dictionary encoding gave up
# and zstd compressed raw float32 bytes poorly; BYTE_STREAM_SPLIT (each float's 4 bytes in 4
# streams: the exponents together) lets zstd work, a pair of 975-character zoo shards 31% smaller,
# lossless. (s_cos keeps the dictionary: its cosines repeat, shared canonical names.)
COLUMN_ENCODING = {"pairs": {"m_sink.list.element": "BYTE_STREAM_SPLIT"}}

# Rows per Parquet row group: small for large per-row arrays, so one record reads on its own.
ROW_GROUP_SIZE = {"characters": 8, "motions": 16, "pairs": 256, "cases": 256, "status": 4096, "results": 4096,
                  "rigid_bodies": 4096, "joints": 4096}

# Rows per shard, by table; a stage named in ROWS_PER_SHARD_OF_STAGE writes that table with its own
# count (kept so that datasets made before this table keep their shard bytes). Memory holds one
# shard while writing: characters of full meshes are the heaviest rows.
ROWS_PER_SHARD = {"characters": 500, "motions": 500, "pairs": 5000, "cases": 5000, "status": 1000, "results": 1000,
                  "rigid_bodies": 4096, "joints": 4096}
ROWS_PER_SHARD_OF_STAGE = {("zoo", "characters"): 1000, ("ingest", "characters"): 200, ("ingest", "motions"): 200,
                           ("ingest", "rigid_bodies"): 100000, ("ingest", "joints"): 100000,
                           ("retarget", "characters"): 200, ("retarget", "motions"): 200}


def rows_per_shard(table: str, stage: str | None = None) -> int:
    """Rows a shard of ``table`` written by ``stage`` (see :data:`ROWS_PER_SHARD`)."""
    return ROWS_PER_SHARD_OF_STAGE.get((stage, table), ROWS_PER_SHARD[table])


def record_type(table: str) -> type:
    """The record class of ``table``; raises KeyError naming the known tables."""
    try:
        return RECORD_TYPES[table]
    except KeyError:
        raise KeyError(f"unknown table {table!r}; expected one of {sorted(RECORD_TYPES)}") from None


def schema_of(table: str):
    """The versioned Arrow schema of ``table``."""
    return arrow_schema(record_type(table).COLUMNS, table)
