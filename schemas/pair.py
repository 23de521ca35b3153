"""A ground-truth correspondence between two characters' keypoints (table ``pairs``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.columns import Column

TABLE = "pairs"


@dataclass
class PairRecord:
    """Correspondence ground truth for (source, target), made by ``method``.

    ``s_cos`` (K1, K2) float32 cosine similarity of the canonical bone-name embeddings (the
    paper's S_cos, whatever the method); ``hungarian`` (P, 2) int32 (source keypoint, target
    keypoint) pairs, M_hung; ``m_sink`` (K1, K2) float32 Sinkhorn soft matching, M_sink.
    Method ``text`` (the paper's): P = min(K1, K2), M_sink of exp(S_cos / T) with rows summing to
    1 and columns to K1/K2. Method ``structure``: the score combines S_cos with skeleton
    features, P <= min(K1, K2) (bones without a counterpart stay unmatched), M_sink rows sum to
    at most 1 (the rest is the no-match probability). ``method_params`` holds the weights.
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
    method: str | None = None
    method_params: dict | None = None

    COLUMNS = (
        Column("pair_id", "scalar", "string", doc="`<source_id>-><target_id>`"),
        Column("source_id", "scalar", "string", doc="source character ID"),
        Column("target_id", "scalar", "string", doc="target character ID"),
        Column("split", "scalar", "string", doc="split both characters belong to, or \"across\" for pairs between characters of different splits (correspond --pairs-across-splits)"),
        Column("k1", "scalar", "int32", doc="source keypoint count K1"),
        Column("k2", "scalar", "int32", doc="target keypoint count K2"),
        Column("s_cos", "list", "float32", reshape=("k1", "k2"), doc="(K1*K2,) stored row-major, (K1, K2) in memory: cosine similarity"),
        Column("hungarian", "rows", "int32", 2, doc="(P, 2) matched (source, target) keypoint indices (M_hung); P = min(K1, K2) for method `text`, P <= min(K1, K2) for `structure` (no-match threshold)"),
        Column("m_sink", "list", "float32", reshape=("k1", "k2"), doc="(K1*K2,) stored, (K1, K2) in memory: Sinkhorn soft matching (M_sink); rows sum to 1 (`text`) or at most 1 (`structure`)"),
        Column("encoder", "scalar", "string", doc="text encoder name and version, e.g. `minilm:all-MiniLM-L6-v2`"),
        Column("temperature", "scalar", "float32", doc="Sinkhorn temperature T"),
        Column("source_category", "scalar", "string", doc="source category"),
        Column("target_category", "scalar", "string", doc="target category"),
        Column("method", "scalar", "string", nullable=True, doc="`structure` (default) or `text` (the paper's); null in data written before methods were recorded (text)"),
        Column("method_params", "json", nullable=True, doc="JSON object: the method's name, weights (text, side, axial, along, hop, part, depth, position), no_match threshold and temperature"),
    )
