"""Turn a method's raw output into metrics for one case, or a reason it failed."""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.metrics import els, pmd, pmd_aligned, pmd_squared
from mimicbench.benchmark.normalisation import RestFrame


class InvalidPrediction(ValueError):
    """A method returned something that is not (Nt, 3) finite floats."""


def check_prediction(pred, num_vertices) -> np.ndarray:
    """Return ``pred`` as (Nt, 3) float32, or raise :class:`InvalidPrediction` saying what is wrong.

    ``num_vertices`` is Nt, or the whole expected shape as a tuple (a motion request's (F, N, 3)).
    """
    shape = tuple(num_vertices) if isinstance(num_vertices, tuple) else (num_vertices, 3)
    if pred is None:
        raise InvalidPrediction("method returned None")
    try:
        arr = np.asarray(pred.detach().cpu().numpy() if hasattr(pred, "detach") else pred)
    except Exception as exc:
        raise InvalidPrediction(f"output is not an array ({type(pred).__name__}): {exc}") from exc
    if arr.shape != shape:
        raise InvalidPrediction(f"wrong shape: expected {shape}, got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise InvalidPrediction(f"wrong dtype: expected float32, got {arr.dtype}")
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=-1).sum())
        raise InvalidPrediction(f"non-finite output: {bad} vertices are NaN or inf")
    return arr.astype(np.float32)


def score_pose(pred: np.ndarray, ref: np.ndarray, frame: RestFrame, headline: str) -> dict:
    """Every pose metric of predicted (N, 3) vs reference (N, 3) vertices in one rest frame.

    Returns the result columns ``pmd`` (normalised by ``headline``: ``height`` or ``extent``),
    ``pmd_height``, ``pmd_extent``, ``pmd_aligned`` and ``pmd_squared`` (both by ``headline``)
    and ``els`` (over ``frame.edges``).
    """
    if frame.edges is None:
        raise ValueError("frame: expected a RestFrame with edges (RestFrame.of(vertices, edges))")
    frame.scale(headline)  # raises on an unknown name
    by = {"height": pmd(pred, ref, frame, "height"), "extent": pmd(pred, ref, frame, "extent")}
    return {"pmd": by[headline], "pmd_height": by["height"], "pmd_extent": by["extent"],
            "pmd_aligned": pmd_aligned(pred, ref, frame, headline),
            "pmd_squared": pmd_squared(pred, ref, frame, headline),
            "els": els(pred, ref, frame.edges)}
