"""MMD's keyframe interpolation curves.

A VMD bone key stores four cubic Bezier curves (x, y, z translation and rotation), each from
(0, 0) to (1, 1) with two control points (x1, y1), (x2, y2) given as bytes 0..127 (/127). The
curve stored on key k shapes the segment from key k-1 to key k: for a time fraction u of that
segment, solve x(s) = u for s, and the blend weight is y(s) (MMD solves by bisection; so do we).
"""
from __future__ import annotations

import numpy as np

CHANNELS = ("x", "y", "z", "rotation")


def control_points(interpolation: bytes | np.ndarray) -> np.ndarray:
    """(4, 4) float64: for each channel (x, y, z, rotation) its (x1, y1, x2, y2) in [0, 1], from a
    VMD bone key's 64 interpolation bytes (the first row of 16 holds them: x1 of the four channels,
    then y1, then x2, then y2)."""
    ip = np.frombuffer(bytes(interpolation), np.uint8)
    if ip.size != 64:
        raise ValueError(f"interpolation: expected 64 bytes, got {ip.size}")
    return ip[:16].reshape(4, 4).T.astype(np.float64) / 127.0


def _cubic(s: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """The 1-D cubic Bezier with end points 0 and 1 and control values p1, p2, at parameter s."""
    r = 1.0 - s
    return 3.0 * r * r * s * p1 + 3.0 * r * s * s * p2 + s * s * s


def bezier_weight(u: np.ndarray, x1, y1, x2, y2, iterations: int = 40) -> np.ndarray:
    """Blend weights y(s) where x(s) = u, for time fractions u (...) in [0, 1] (bisection on s;
    x(s) is monotonic for control points in [0, 1]). Control values broadcast against u."""
    u = np.clip(np.asarray(u, np.float64), 0.0, 1.0)
    x1, y1, x2, y2 = (np.asarray(a, np.float64) for a in (x1, y1, x2, y2))
    lo = np.zeros(np.broadcast(u, x1).shape)
    hi = np.ones_like(lo)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = _cubic(mid, x1, x2) < u
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return _cubic(0.5 * (lo + hi), y1, y2)
