"""One scored benchmark case for one method (results table, not part of a dataset).

Metric columns (all x100 PMDs are percentages of a rest mesh's length; see FORMAT.md,
"Normalisation for metrics"):

- ``pmd``: the protocol's headline PMD. ``h2h``: by the target's height (the papers'
  convention); ``cct``: by the source's largest extent (the cycle returns to the source).
- ``pmd_height``: PMD by the height (Y extent) of the same rest mesh, comparable with
  skeleton-free pose transfer and MimiCAT tables.
- ``pmd_extent``: PMD by the largest bounding-box side of the same rest mesh, one scale for
  every kind of character.
- ``pmd_aligned``: ``pmd`` (same normalisation) after centring prediction and reference on their
  own centroids: articulation without global translation.
- ``pmd_squared``: NPT-style squared PMD, headline normalisation.
- ``els``, ``els_forward``: edge length scores (scale-free).

``status``: ``ok``, ``failed`` (the method raised, timed out or returned something invalid;
``error`` says what) or ``not_supported`` (the method's metadata does not list the protocol; it
was not run). Only ``ok`` rows carry metrics.
"""
from __future__ import annotations

from dataclasses import dataclass

from schemas.columns import Column

TABLE = "results"
OK, FAILED, NOT_SUPPORTED = "ok", "failed", "not_supported"
STATUSES = (OK, FAILED, NOT_SUPPORTED)


@dataclass
class ResultRecord:
    """Metrics of one method on one case; failed and unsupported cases have null metrics."""

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
    pmd_height: float | None = None
    pmd_extent: float | None = None
    pmd_aligned: float | None = None

    COLUMNS = (
        Column("case_id", "scalar", "string", doc="the case scored"),
        Column("protocol", "scalar", "string", doc="`h2h`, `cct` or `apparel`"),
        Column("method", "scalar", "string", doc="registered method name"),
        Column("method_version", "scalar", "string", doc="method version"),
        Column("status", "scalar", "string", doc="`ok`, `failed` or `not_supported` (the method's metadata does not list the protocol; not run)"),
        Column("error", "scalar", "string", nullable=True, doc="why the case failed (exception, NaN, wrong shape) or is not supported; null when ok"),
        Column("seconds", "scalar", "float64", doc="wall-clock seconds the method spent on the case"),
        Column("pmd", "scalar", "float64", nullable=True, doc="headline PMD x100: h2h by the target's height, cct (the cycle's return) by the source's largest extent"),
        Column("pmd_squared", "scalar", "float64", nullable=True, doc="NPT-style squared-distance PMD x100, headline normalisation"),
        Column("els", "scalar", "float64", nullable=True, doc="edge length score, 1 is perfect; cct: of the return leg"),
        Column("els_forward", "scalar", "float64", nullable=True, doc="cct: ELS of the forward leg's prediction on the target"),
        Column("source_category", "scalar", "string", doc="source category"),
        Column("target_category", "scalar", "string", doc="target category"),
        Column("pmd_height", "scalar", "float64", nullable=True, doc="PMD x100 by the rest mesh's height (Y extent): the papers' convention"),
        Column("pmd_extent", "scalar", "float64", nullable=True, doc="PMD x100 by the rest mesh's largest bounding-box side: one scale for every shape"),
        Column("pmd_aligned", "scalar", "float64", nullable=True, doc="headline PMD x100 after centring both meshes on their own centroids (articulation without global translation)"),
    )
