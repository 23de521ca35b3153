"""Why an asset did or did not make it through a stage (table ``status``)."""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.schemas.columns import Column

TABLE = "status"


@dataclass
class StatusRecord:
    """One asset at one stage: ``ok``, ``failed`` or ``skipped``, with the reason."""

    asset: str
    stage: str
    status: str
    reason: str
    seconds: float = 0.0

    COLUMNS = (
        Column("asset", "scalar", "string", doc="asset path or character ID"),
        Column("stage", "scalar", "string", doc="`zoo`, `ingest`, `resample`, `correspond`, ..."),
        Column("status", "scalar", "string", doc="`ok`, `failed` or `skipped`"),
        Column("reason", "scalar", "string", doc="empty when ok; otherwise what went wrong, in words"),
        Column("seconds", "scalar", "float64", doc="wall-clock seconds spent"),
    )
