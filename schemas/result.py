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
- ``semantic_deg``, ``role_classes_scored``, ``out_of_range``: the forward prediction against hidden
  ground truth (role classes; the target's own range of motion), see ``benchmark/semantic.py`` and
  ``benchmark/motion_range.py``.
- ``apparel`` protocol (means over the window's frames; ``*_frames`` per frame): ``pmd`` and
  ``pmd_height`` over all vertices, ``pmd_apparel`` over the ground truth's apparel vertices,
  ``pmd_body`` over the other vertices (x100 of the target's height), the same in centimetres
  of the character scaled to 1.70 m (``pmd_cm``, ``pmd_apparel_cm``, ``pmd_body_cm``, MMDMC's
  unit), and ``els``; over the window as a whole, ``accel_error`` (mean |a_pred - a_gt| over apparel
  vertices and second differences, m/s^2 at 1.70 m height) and ``penetration_share`` (percent of
  apparel vertices within 1 mm at 1.70 m of the body or inside it, HOOD's measure); see
  ``benchmark/apparel_metrics.py``.

``status``: ``ok``, ``failed`` (the method raised, timed out or returned something invalid;
``error`` says what) or ``not_supported`` (the method's metadata does not list the protocol; it
was not run). Only ``ok`` rows carry metrics.
"""
from __future__ import annotations

from dataclasses import dataclass

from mimicbench.schemas.columns import Column

TABLE = "results"
APPAREL_METRICS = ("pmd_apparel", "pmd_body", "pmd_cm", "pmd_apparel_cm", "pmd_body_cm", "pmd_frames",
                   "pmd_apparel_frames", "pmd_body_frames", "els_frames", "accel_error", "penetration_share")
"""Result columns only the ``apparel`` protocol fills."""
FORWARD_METRICS = ("semantic_deg", "role_classes_scored", "out_of_range")
"""Result columns that score the forward prediction against hidden ground truth (``h2h``, ``h2h_xskel``, ``cct``)."""
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
    pmd_apparel: float | None = None
    pmd_body: float | None = None
    pmd_cm: float | None = None
    pmd_apparel_cm: float | None = None
    pmd_body_cm: float | None = None
    pmd_frames: list | None = None
    pmd_apparel_frames: list | None = None
    pmd_body_frames: list | None = None
    els_frames: list | None = None
    accel_error: float | None = None
    penetration_share: float | None = None
    semantic_deg: float | None = None
    role_classes_scored: int | None = None
    out_of_range: float | None = None

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
        Column("pmd_apparel", "scalar", "float64", nullable=True, doc="apparel: PMD x100 (target's height) over the ground truth's apparel vertices, mean over the window"),
        Column("pmd_body", "scalar", "float64", nullable=True, doc="apparel: PMD x100 (target's height) over the other (body) vertices, mean over the window"),
        Column("pmd_cm", "scalar", "float64", nullable=True, doc="apparel: PMD over all vertices in cm of the character scaled to 1.70 m height"),
        Column("pmd_apparel_cm", "scalar", "float64", nullable=True, doc="apparel: PMD_a in cm at 1.70 m height"),
        Column("pmd_body_cm", "scalar", "float64", nullable=True, doc="apparel: PMD_b in cm at 1.70 m height"),
        Column("pmd_frames", "list", "float64", nullable=True, doc="apparel: (F,) PMD x100 of each frame of the window"),
        Column("pmd_apparel_frames", "list", "float64", nullable=True, doc="apparel: (F,) PMD_a x100 of each frame"),
        Column("pmd_body_frames", "list", "float64", nullable=True, doc="apparel: (F,) PMD_b x100 of each frame"),
        Column("els_frames", "list", "float64", nullable=True, doc="apparel: (F,) ELS of each frame"),
        Column("accel_error", "scalar", "float64", nullable=True, doc="apparel: mean over apparel vertices and the window's second differences of the length of a_pred - a_gt (accelerations at the clip's fps), m/s^2 of the character scaled to 1.70 m height"),
        Column("penetration_share", "scalar", "float64", nullable=True, doc="apparel: percent of apparel vertices (those clear of the body at rest) within 1 mm (at 1.70 m height) of the ground truth's body pieces or inside them, mean over the window (HOOD)"),
        Column("semantic_deg", "scalar", "float64", nullable=True, doc="forward leg: mean degrees between how each role class of the target moved and how the source's counterpart moved, in each character's body frame (benchmark/semantic.py); lower is better; null when either character has no role labels"),
        Column("role_classes_scored", "scalar", "int64", nullable=True, doc="forward leg: how many parts (the body and the role classes both characters have) `semantic_deg` averages; null when it is null"),
        Column("out_of_range", "scalar", "float64", nullable=True, doc="forward leg: share of the target's bones rotated beyond the range its own clips reach, by more than the margin of benchmark/motion_range.py; lower is better"),
    )
