"""Pose-transfer metrics, NumPy (the torch twins are in :mod:`benchmark.metrics_torch`).

All distances are measured after normalising by the **target's rest mesh**: centre at its
bounding-box centre and divide by its height (Y extent), so PMD x100 is a percentage of height.

- PMD (point-wise mesh distance; MimiCAT, Sec. 5): mean over vertices of the Euclidean distance
  between predicted and reference vertices, x100.
- PMD squared (the Neural Pose Transfer variant, Wang et al., CVPR 2020): mean over vertices of
  the squared Euclidean distance, in unit-height units squared, x100.
- ELS (edge length score; Liao et al., "Skeleton-free pose transfer", ECCV 2022):
  ``1 - mean over unique edges |l_pred / l_ref - 1|``, no clamp; 1 is perfect.
"""
from __future__ import annotations

import numpy as np

from mimicbench.mesh import edge_lengths, unit_height_frame


def pmd(pred: np.ndarray, ref: np.ndarray, target_rest_vertices: np.ndarray) -> float:
    """PMD x100 of predicted (N, 3) vs reference (N, 3) vertices, in the target's unit height."""
    _, height = unit_height_frame(target_rest_vertices)
    d = np.linalg.norm((np.asarray(pred, np.float64) - np.asarray(ref, np.float64)) / height, axis=-1)
    return float(d.mean() * 100.0)


def pmd_squared(pred: np.ndarray, ref: np.ndarray, target_rest_vertices: np.ndarray) -> float:
    """NPT-style PMD: mean squared vertex distance in unit-height units, x100."""
    _, height = unit_height_frame(target_rest_vertices)
    d2 = np.sum(((np.asarray(pred, np.float64) - np.asarray(ref, np.float64)) / height) ** 2, axis=-1)
    return float(d2.mean() * 100.0)


def els(pred: np.ndarray, ref: np.ndarray, edges: np.ndarray, eps: float = 1e-12) -> float:
    """Edge length score of predicted (N, 3) vs reference (N, 3) vertices over edges (E, 2).

    Edges whose reference length is below ``eps`` are ignored (they have no ratio).
    """
    lp = edge_lengths(np.asarray(pred, np.float64), edges)
    lr = edge_lengths(np.asarray(ref, np.float64), edges)
    keep = lr > eps
    return float(1.0 - np.mean(np.abs(lp[keep] / lr[keep] - 1.0)))
