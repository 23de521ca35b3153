"""The bound on a clip's length in frames, checked before any per-frame array is allocated.

One key far in the future (a VMD key at frame 2^31, a glTF key at t = 1e7 s, a BVH header that
says ``Frames: 999999999``) would otherwise make ingest ask for terabytes. Every format's clip is
checked against ``--max-clip-frames`` (default :data:`MAX_CLIP_FRAMES`, 20 minutes at 30 fps:
about 1.7 GB of per-frame bone matrices for a 224-bone MMD model) before it is sampled; a longer
clip becomes a failed status row that names the limit and the option that raises it.
"""
from __future__ import annotations

MAX_CLIP_FRAMES = 36_000


class ClipTooLong(ValueError):
    """A clip has more frames than the bound (the message names both and ``--max-clip-frames``)."""


def check_clip_frames(frames: int | float, what: str, limit: int | None = None) -> int:
    """Return ``frames`` as an int if it is at most ``limit`` (default :data:`MAX_CLIP_FRAMES`).

    Args:
        frames: number of frames the clip would have (a float is accepted: a key time times fps).
        what: the clip, for the message (``"clip 'Run'"``, ``"motion.vmd"``).

    Raises:
        ClipTooLong: ``frames`` is above the limit (or not a finite number).
    """
    limit = MAX_CLIP_FRAMES if limit is None else int(limit)
    if not frames == frames or frames in (float("inf"), float("-inf")) or frames > limit:
        shown = f"{frames:.4g}" if isinstance(frames, float) else f"{frames}"
        raise ClipTooLong(f"{what}: {shown} frames exceed the clip length bound of {limit} frames "
                          f"(raise it with --max-clip-frames N)")
    return int(frames)
