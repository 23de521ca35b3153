"""Sparse skin weights: at most J influences a vertex, stored as fixed-width index/value arrays.

``indices`` (N, J) int32 and ``values`` (N, J) float32; unused slots have value 0 (and any valid
index, conventionally 0). Rows of ``values`` sum to 1. The dense form is (N, K) float.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_INFLUENCES = 8


@dataclass(frozen=True)
class SparseWeights:
    """Skin weights of N vertices over K keypoints, J influences a vertex at most.

    Attributes:
        indices: (N, J) int32 keypoint index of each influence.
        values: (N, J) float32 weight of each influence; 0 marks an unused slot.
        num_keypoints: K.
    """

    indices: np.ndarray
    values: np.ndarray
    num_keypoints: int

    def __post_init__(self):
        if self.indices.shape != self.values.shape or self.indices.ndim != 2:
            raise ValueError(
                f"SparseWeights: expected indices and values of one shape (N, J), got "
                f"{self.indices.shape} and {self.values.shape}"
            )
        if self.indices.size and (self.indices.min() < 0 or self.indices.max() >= self.num_keypoints):
            raise ValueError(
                f"SparseWeights: indices must lie in [0, {self.num_keypoints}), got range "
                f"[{self.indices.min()}, {self.indices.max()}]"
            )

    @property
    def num_vertices(self) -> int:
        return int(self.indices.shape[0])

    def to_dense(self, dtype=np.float32) -> np.ndarray:
        """Dense weights (N, K)."""
        dense = np.zeros((self.num_vertices, self.num_keypoints), dtype=dtype)
        rows = np.repeat(np.arange(self.num_vertices), self.indices.shape[1])
        np.add.at(dense, (rows, self.indices.ravel()), self.values.ravel())
        return dense

    @classmethod
    def from_dense(cls, dense: np.ndarray, max_influences: int = MAX_INFLUENCES,
                   normalize: bool = True) -> "SparseWeights":
        """Keep the ``max_influences`` largest weights of each row of dense (N, K), renormalised."""
        dense = np.asarray(dense, dtype=np.float64)
        if dense.ndim != 2:
            raise ValueError(f"dense: expected shape (N, K), got {dense.shape}")
        columns = np.broadcast_to(np.arange(dense.shape[1]), dense.shape)
        return cls._from_rows(columns, dense, dense.shape[1], max_influences, normalize)

    @classmethod
    def from_csr(cls, matrix, max_influences: int = MAX_INFLUENCES, normalize: bool = True) -> "SparseWeights":
        """The same as ``from_dense(matrix.toarray())`` for a scipy sparse (N, K) matrix, without
        the dense (N, K) array: duplicates are summed, then each row keeps its largest weights."""
        from scipy.sparse import csr_matrix

        m = csr_matrix(matrix, dtype=np.float64, copy=True)
        m.sum_duplicates()
        n, k = m.shape
        counts = np.diff(m.indptr)
        width = max(int(counts.max(initial=0)), 1)
        rows = np.repeat(np.arange(n), counts)
        slot = np.arange(m.nnz) - m.indptr[rows]
        values = np.zeros((n, width))
        columns = np.zeros((n, width), np.int64)
        values[rows, slot] = m.data
        columns[rows, slot] = m.indices
        return cls._from_rows(columns, values, k, max_influences, normalize)

    @classmethod
    def _from_rows(cls, columns: np.ndarray, values: np.ndarray, k: int, max_influences: int,
                   normalize: bool) -> "SparseWeights":
        """Top ``max_influences`` of candidate (column, value) rows (N, C), columns ascending per row."""
        j = min(max_influences, values.shape[1])
        order = np.argsort(-values, axis=1, kind="stable")[:, :j]
        val = np.take_along_axis(values, order, axis=1)
        idx = np.take_along_axis(columns, order, axis=1)
        val = np.where(val > 0, val, 0.0)
        idx = np.where(val > 0, idx, 0)
        if normalize:
            s = val.sum(axis=1, keepdims=True)
            if (s <= 0).any():
                raise ValueError(
                    f"weights: {int((s <= 0).sum())} vertices have no positive weight; every vertex "
                    "must be weighted"
                )
            val = val / s
        if j < max_influences:
            pad = max_influences - j
            idx = np.pad(idx, ((0, 0), (0, pad)))
            val = np.pad(val, ((0, 0), (0, pad)))
        return cls(idx.astype(np.int32), val.astype(np.float32), k)

    def take(self, rows: np.ndarray) -> "SparseWeights":
        """The weights of the vertices ``rows`` (an index or boolean array), in that order."""
        return SparseWeights(self.indices[rows], self.values[rows], self.num_keypoints)

    def to_csr(self):
        """The weights as a ``scipy.sparse.csr_matrix`` (N, K) float64 (cached)."""
        cached = getattr(self, "_csr", None)
        if cached is None:
            from scipy.sparse import csr_matrix

            n, j = self.indices.shape
            rows = np.repeat(np.arange(n), j)
            cached = csr_matrix((self.values.ravel().astype(np.float64), (rows, self.indices.ravel())),
                                shape=(n, self.num_keypoints))
            object.__setattr__(self, "_csr", cached)
        return cached

    def dominant(self) -> np.ndarray:
        """(N,) int64 the keypoint of each vertex's largest weight, the lowest one of a tie (the dense
        form's ``argmax``, without building it)."""
        best = self.values.max(axis=1, keepdims=True)
        return np.where(self.values >= best, self.indices, np.iinfo(np.int32).max).min(axis=1).astype(np.int64)

    def row_sums(self) -> np.ndarray:
        """Sum of each vertex's weights (N,)."""
        return self.values.astype(np.float64).sum(axis=1)


def as_dense(weights, num_keypoints: int | None = None) -> np.ndarray:
    """Return weights (N, K) dense from a dense array or a :class:`SparseWeights`."""
    if isinstance(weights, SparseWeights):
        return weights.to_dense(np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or (num_keypoints is not None and w.shape[1] != num_keypoints):
        raise ValueError(f"weights: expected shape (N, {num_keypoints or 'K'}), got {w.shape}")
    return w
