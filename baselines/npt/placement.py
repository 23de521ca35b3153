"""Where NPT and CGT see the meshes, and where their answer is put back.

Neural Pose Transfer ignores global translation (its maintainers say so; its evaluation centres
both meshes). We do the same and then restore the placement:

- the posed source is centred at its own bounding-box centre and divided by its rest mesh's size
  (the largest side of its box, :func:`mimicbench.benchmark.normalisation.largest_extent`);
- the target rest mesh is centred at its bounding-box centre and divided by its size;
- the network answers the posed target in that centred unit-size frame (training targets are
  the ground truth centred at its own box centre);
- :func:`place` multiplies by the target's size and adds the target's rest centre plus the
  source's displacement (posed box centre minus rest box centre) scaled by
  :func:`mimicbench.benchmark.normalisation.size_ratio`, the h2h ground truth's rule for root motion.

Dividing by the size is ours (NPT's SMPL meshes share one scale; zoo characters do not, and a
snake's height is a small part of its length, so its size, not its height, keeps it in NPT's
2 tanh range).
Global orientation is not removed: the network sees the posed source as it stands.
"""
from __future__ import annotations

import numpy as np

from mimicbench.benchmark.normalisation import largest_extent, size_ratio


def box_centre(vertices: np.ndarray) -> np.ndarray:
    """(3,) float64 centre of the axis-aligned bounding box of vertices (N, 3)."""
    v = np.asarray(vertices, np.float64)
    return (v.min(0) + v.max(0)) / 2.0


def centred(vertices: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(N, 3) float32: ``vertices`` minus their own box centre, divided by the size of ``rest`` (N', 3)."""
    return ((np.asarray(vertices, np.float64) - box_centre(vertices)) / largest_extent(rest)).astype(np.float32)


def place(answer: np.ndarray, source_rest: np.ndarray, source_posed: np.ndarray, target_rest: np.ndarray) -> np.ndarray:
    """(Nt, 3) float32 metres: the network's centred unit-size answer (Nt, 3) put where the target stands,
    moved as the source moved from its rest placement."""
    shift = (box_centre(source_posed) - box_centre(source_rest)) * size_ratio(source_rest, target_rest)
    return (np.asarray(answer, np.float64) * largest_extent(target_rest) + box_centre(target_rest)
            + shift).astype(np.float32)
