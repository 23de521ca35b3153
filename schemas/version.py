"""The data contract's version, stored in every shard's Arrow metadata and in manifest.json.

Bump the major number for a change that old readers cannot read (a column removed, renamed or
retyped); bump the minor number for an added nullable column or table.

Each version and what it added: CHANGELOG.md.
"""
SCHEMA_VERSION = "1.3"
METADATA_KEY = b"mimicbench.schema_version"
TABLE_KEY = b"mimicbench.table"


def _parts(version: str) -> tuple[int, int]:
    parts = version.split(".")
    return int(parts[0]), int(parts[1]) if len(parts) > 1 else 0


def is_compatible(version: str) -> bool:
    """True when data written at ``version`` can be read by this code (same major version)."""
    try:
        return _parts(version)[0] == _parts(SCHEMA_VERSION)[0]
    except (AttributeError, ValueError):
        return False


def newer(a: str, b: str) -> str:
    """The later of two compatible versions (a manifest never goes back to an older minor)."""
    return a if _parts(a) >= _parts(b) else b
