"""A motion clip of one character (table ``motions``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.schemas.columns import Column

TABLE = "motions"

SIM_SUFFIX = "@sim"
"""A simulated clip's motion ID and name: the kinematic clip's followed by this (``datagen apparel``
writes the pair, the benchmark's apparel protocol and the MMDMC reference pair them by it)."""


@dataclass
class MotionRecord:
    """One clip: per-frame per-keypoint transforms at ``fps`` frames per second.

    ``transforms`` (F, K, 7) float32: unit quaternion (w, x, y, z) of bone k's world rotation
    relative to rest, then the posed world position of keypoint k (metres). K and the bone order
    are those of the character ``character_id``. Frame f is at time ``t0 + f / fps`` of the
    source clip (``t0`` its first key).

    ``scale`` (F, K, 6) float32 or None: for clips whose bones scale (or shear), each bone's
    symmetric stretch U in the rest frame (``s_xx, s_yy, s_zz, s_xy, s_xz, s_yz``), so that the
    bone maps rest to posed as ``R(q) U (v - c) + t``; None when every bone moves rigidly.
    """

    motion_id: str
    character_id: str
    name: str
    split: str
    fps: float
    num_frames: int
    num_joints: int
    transforms: np.ndarray
    source: str = ""
    scale: np.ndarray | None = None

    COLUMNS = (
        Column("motion_id", "scalar", "string", doc="stable ID, `<character_id>/<clip name>`"),
        Column("character_id", "scalar", "string", doc="the character whose skeleton the clip drives"),
        Column("name", "scalar", "string", doc="clip name as authored (e.g. `Walk`) or generated (`gait`)"),
        Column("split", "scalar", "string", doc="split of the character"),
        Column("fps", "scalar", "float32", doc="frames per second"),
        Column("num_frames", "scalar", "int32", doc="F"),
        Column("num_joints", "scalar", "int32", doc="K"),
        Column("transforms", "rows", "float32", 7, reshape=("num_frames", "num_joints", 7),
               doc="(F*K, 7) stored, (F, K, 7) in memory: q_w, q_x, q_y, q_z, t_x, t_y, t_z per frame and keypoint"),
        Column("source", "scalar", "string", doc="generator or file the clip came from"),
        Column("scale", "rows", "float32", 6, nullable=True, reshape=("num_frames", "num_joints", 6),
               doc="(F*K, 6) stored, (F, K, 6) in memory, or null: per frame and keypoint the symmetric stretch U "
                   "(s_xx, s_yy, s_zz, s_xy, s_xz, s_yz, rest frame) of a bone that scales; LBS then maps "
                   "R(q) U (v - c) + t; null when all bones move rigidly"),
    )
