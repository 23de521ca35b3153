"""The data contract's version, stored in every shard's Arrow metadata and in manifest.json.

Bump the major number for a change that old readers cannot read (a column removed, renamed or
retyped); bump the minor number for an added nullable column.
"""
SCHEMA_VERSION = "1.0"
METADATA_KEY = b"mimicbench.schema_version"
TABLE_KEY = b"mimicbench.table"


def is_compatible(version: str) -> bool:
    """True when data written at ``version`` can be read by this code (same major version)."""
    try:
        return version.split(".")[0] == SCHEMA_VERSION.split(".")[0]
    except AttributeError:
        return False
