"""Sparse skin weights, offered under their public name; defined in :mod:`schemas.weights`."""
from __future__ import annotations

from schemas.weights import MAX_INFLUENCES, SparseWeights, as_dense

__all__ = ["MAX_INFLUENCES", "SparseWeights", "as_dense"]
