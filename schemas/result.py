"""One scored benchmark case for one method (results table, not part of a dataset)."""
from __future__ import annotations

from dataclasses import dataclass

from schemas.columns import Column

TABLE = "results"


@dataclass
class ResultRecord:
    """Metrics of one method on one case; failed cases have null metrics and an error."""

    case_id: str
    protocol: str
    method: str
    method_version: str
    status: str
    error: str | None
    seconds: float
    pmd: float | None
    pmd_squared: float | None
    els: float | None
    els_forward: float | None
    source_category: str
    target_category: str

    COLUMNS = (
        Column("case_id", "scalar", "string", doc="the case scored"),
        Column("protocol", "scalar", "string", doc="`h2h`, `cct` or `apparel`"),
        Column("method", "scalar", "string", doc="registered method name"),
        Column("method_version", "scalar", "string", doc="method version"),
        Column("status", "scalar", "string", doc="`ok` or `failed`"),
        Column("error", "scalar", "string", nullable=True, doc="why the case failed (exception, NaN, wrong shape); null when ok"),
        Column("seconds", "scalar", "float64", doc="wall-clock seconds the method spent on the case"),
        Column("pmd", "scalar", "float64", nullable=True, doc="PMD x100 (percent of target height); cct: of the cycle's return"),
        Column("pmd_squared", "scalar", "float64", nullable=True, doc="NPT-style squared-distance PMD x100 on the same normalised meshes"),
        Column("els", "scalar", "float64", nullable=True, doc="edge length score, 1 is perfect; cct: of the return leg"),
        Column("els_forward", "scalar", "float64", nullable=True, doc="cct: ELS of the forward leg's prediction on the target"),
        Column("source_category", "scalar", "string", doc="source category"),
        Column("target_category", "scalar", "string", doc="target category"),
    )
