"""A text-guided correspondence between two characters' keypoints (table ``pairs``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from schemas.columns import Column

TABLE = "pairs"


@dataclass
class PairRecord:
    """Bone-name correspondence ground truth for (source, target).

    ``s_cos`` (K1, K2) float32 cosine similarity of the canonical bone-name embeddings;
    ``hungarian`` (P, 2) int32 (source keypoint, target keypoint) pairs, P = min(K1, K2);
    ``m_sink`` (K1, K2) float32 Sinkhorn of exp(S_cos / temperature), rows sum to 1 and columns
    to K1/K2.
    """

    pair_id: str
    source_id: str
    target_id: str
    split: str
    k1: int
    k2: int
    s_cos: np.ndarray
    hungarian: np.ndarray
    m_sink: np.ndarray
    encoder: str
    temperature: float
    source_category: str = ""
    target_category: str = ""

    COLUMNS = (
        Column("pair_id", "scalar", "string", doc="`<source_id>-><target_id>`"),
        Column("source_id", "scalar", "string", doc="source character ID"),
        Column("target_id", "scalar", "string", doc="target character ID"),
        Column("split", "scalar", "string", doc="split both characters belong to"),
        Column("k1", "scalar", "int32", doc="source keypoint count K1"),
        Column("k2", "scalar", "int32", doc="target keypoint count K2"),
        Column("s_cos", "list", "float32", reshape=("k1", "k2"), doc="(K1*K2,) stored row-major, (K1, K2) in memory: cosine similarity"),
        Column("hungarian", "rows", "int32", 2, doc="(P, 2) matched (source, target) keypoint indices, P = min(K1, K2)"),
        Column("m_sink", "list", "float32", reshape=("k1", "k2"), doc="(K1*K2,) stored, (K1, K2) in memory: Sinkhorn soft matching"),
        Column("encoder", "scalar", "string", doc="text encoder name and version, e.g. `minilm:all-MiniLM-L6-v2`"),
        Column("temperature", "scalar", "float32", doc="Sinkhorn temperature T"),
        Column("source_category", "scalar", "string", doc="source category"),
        Column("target_category", "scalar", "string", doc="target category"),
    )
