"""Pose-transfer metrics, NumPy (the torch twins are in :mod:`mimicbench.benchmark.metrics_torch`).

Distances are measured in the frame of a rest mesh (:class:`mimicbench.benchmark.normalisation.RestFrame`:
the target's for ground truth, the source's for a cycle's return), divided by its height
(``by="height"``, the papers' convention) or its largest extent (``by="extent"``, one scale for
every kind of character); see :mod:`mimicbench.benchmark.normalisation` for why both exist.

- PMD (point-wise mesh distance; MimiCAT, Sec. 5; skeleton-free pose transfer): mean over
  vertices of the Euclidean distance between predicted and reference vertices, x100.
- PMD aligned: PMD after centring each mesh on its own centroid (mean vertex), so a prediction
  that is posed right but placed wrong scores 0: ``pmd - pmd_aligned`` reads as the share of
  global translation, ``pmd_aligned`` as articulation.
- PMD squared (the Neural Pose Transfer variant, Wang et al., CVPR 2020): mean over vertices of
  the squared Euclidean distance, in normalised units squared, x100.
- ELS (edge length score; Liao et al., "Skeleton-free pose transfer", ECCV 2022):
  ``1 - mean over unique edges |l_pred / l_ref - 1|``, no clamp; 1 is perfect. Scale-free.

``frame`` may be a :class:`RestFrame` (derived once per case) or the rest vertices (N, 3).
"""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.normalisation import as_rest_frame
from mimicbench.geometry.mesh import edge_lengths


def _difference(pred, ref, frame, by: str) -> np.ndarray:
    """(N, 3) normalised pred - ref (the centre cancels out, only the scale matters)."""
    scale = as_rest_frame(frame).scale(by)
    return (np.asarray(pred, np.float64) - np.asarray(ref, np.float64)) / scale


def pmd(pred: np.ndarray, ref: np.ndarray, frame, by: str = "height") -> float:
    """PMD x100 of predicted (N, 3) vs reference (N, 3) vertices, in units of the frame's ``by``."""
    return float(np.linalg.norm(_difference(pred, ref, frame, by), axis=-1).mean() * 100.0)


def pmd_aligned(pred: np.ndarray, ref: np.ndarray, frame, by: str = "height") -> float:
    """PMD x100 after moving each of pred (N, 3) and ref (N, 3) to its own centroid."""
    p = np.asarray(pred, np.float64)
    r = np.asarray(ref, np.float64)
    return pmd(p - p.mean(axis=0), r - r.mean(axis=0), frame, by)


def pmd_squared(pred: np.ndarray, ref: np.ndarray, frame, by: str = "height") -> float:
    """NPT-style PMD: mean squared vertex distance in normalised units, x100."""
    return float(np.sum(_difference(pred, ref, frame, by) ** 2, axis=-1).mean() * 100.0)


def els(pred: np.ndarray, ref: np.ndarray, edges: np.ndarray, eps: float = 1e-12) -> float:
    """Edge length score of predicted (N, 3) vs reference (N, 3) vertices over edges (E, 2).

    Edges whose reference length is below ``eps`` are ignored (they have no ratio).
    """
    lp = edge_lengths(np.asarray(pred, np.float64), edges)
    lr = edge_lengths(np.asarray(ref, np.float64), edges)
    keep = lr > eps
    return float(1.0 - np.mean(np.abs(lp[keep] / lr[keep] - 1.0)))
