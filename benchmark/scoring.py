"""Turn a method's raw output into metrics for one case, or a reason it failed."""
from __future__ import annotations

import numpy as np

from benchmark.metrics import els, pmd, pmd_squared


class InvalidPrediction(ValueError):
    """A method returned something that is not (Nt, 3) finite floats."""


def check_prediction(pred, num_vertices: int) -> np.ndarray:
    """Return ``pred`` as (Nt, 3) float32, or raise :class:`InvalidPrediction` saying what is wrong."""
    if pred is None:
        raise InvalidPrediction("method returned None")
    try:
        arr = np.asarray(pred.detach().cpu().numpy() if hasattr(pred, "detach") else pred)
    except Exception as exc:
        raise InvalidPrediction(f"output is not an array ({type(pred).__name__}): {exc}") from exc
    if arr.shape != (num_vertices, 3):
        raise InvalidPrediction(f"wrong shape: expected ({num_vertices}, 3), got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise InvalidPrediction(f"wrong dtype: expected float32, got {arr.dtype}")
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise InvalidPrediction(f"non-finite output: {bad} vertices are NaN or inf")
    return arr.astype(np.float32)


def score_h2h(pred: np.ndarray, gt: np.ndarray, target) -> dict:
    """PMD, squared PMD and ELS of a prediction against the ground-truth posed target."""
    return {"pmd": pmd(pred, gt, target.rig.vertices), "pmd_squared": pmd_squared(pred, gt, target.rig.vertices),
            "els": els(pred, gt, target.edges), "els_forward": None}


def score_cycle(returned: np.ndarray, posed_source: np.ndarray, forward: np.ndarray, source, target) -> dict:
    """Cycle consistency: the returned source vs the posed source (PMD, ELS, in the source's
    unit height), and the forward leg's ELS against the target's rest edge lengths."""
    return {"pmd": pmd(returned, posed_source, source.rig.vertices),
            "pmd_squared": pmd_squared(returned, posed_source, source.rig.vertices),
            "els": els(returned, posed_source, source.edges),
            "els_forward": els(forward, target.rig.vertices, target.edges)}
