"""Sparse skin weights, offered under their public name; defined in :mod:`mimicbench.schemas.weights`."""
from __future__ import annotations

from mimicbench.schemas.weights import MAX_INFLUENCES, SparseWeights, as_dense

__all__ = ["MAX_INFLUENCES", "SparseWeights", "as_dense"]
