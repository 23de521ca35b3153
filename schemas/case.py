"""A benchmark case: one posed source and a target to transfer the pose to (table ``cases``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.columns import Column

TABLE = "cases"


@dataclass
class CaseRecord:
    """One pose-transfer query.

    ``source_transforms`` (Ks, 7) float32 poses the source by LBS (the method sees only the
    posed vertices). ``target_transforms`` (Kt, 7) float32 poses the ground-truth target (h2h,
    same-skeleton: the source's local rotations and local translations carried over bone by
    bone, translations scaled by the size ratio); null where there is no ground truth (cct,
    scored by cycle consistency).
    """

    case_id: str
    protocol: str
    source_id: str
    target_id: str
    motion_id: str
    frame: int
    source_transforms: np.ndarray
    target_transforms: np.ndarray | None
    source_category: str
    target_category: str

    COLUMNS = (
        Column("case_id", "scalar", "string", doc="stable ID `<protocol>/<source_id>-><target_id>/<motion>#<frame>`"),
        Column("protocol", "scalar", "string", doc="`h2h` (same-skeleton), `cct` (cross-category cycle) or `apparel`"),
        Column("source_id", "scalar", "string", doc="source character ID"),
        Column("target_id", "scalar", "string", doc="target character ID"),
        Column("motion_id", "scalar", "string", doc="source motion the pose comes from"),
        Column("frame", "scalar", "int32", doc="frame index in that motion"),
        Column("source_transforms", "rows", "float32", 7, doc="(Ks, 7) source pose"),
        Column("target_transforms", "rows", "float32", 7, nullable=True, doc="(Kt, 7) ground-truth target pose (h2h: local rotations and size-scaled local translations of the source), null without ground truth"),
        Column("source_category", "scalar", "string", doc="source category"),
        Column("target_category", "scalar", "string", doc="target category"),
    )
