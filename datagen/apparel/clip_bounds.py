"""What the apparel stage accepts as a simulated clip: every stored value finite and within a bound.

A clip whose physics went wrong (an absurd ``link_mass`` of 1000 stretched skirts 2.9x and moved
them more than the character's height while the stage reported nothing) is not stored: the
stage fails it with a status row naming the bound it broke. The bounds, on the clip's quality
(:mod:`mimicbench.datagen.apparel.quality`):

- ``max_edge_stretch`` (largest ``|l / l_rest - 1|`` over apparel mesh edges and frames) at most
  :data:`MAX_EDGE_STRETCH`: no apparel edge longer than twice its rest length (or collapsed). The
  stage's own clips stay near 0.1-0.15 on the zoo and reached 0.44 on full-resolution meshes.
- ``secondary_motion_max_pct`` (worst frame's mean distance of apparel vertices from where the
  body's skinning puts them, percent of the character's height) at most
  :data:`MAX_SECONDARY_MOTION_PCT`: apparel that swings, not apparel that left the body. The zoo's
  clips stay under 5%.

and every number of the quality and every value of the clip's transforms finite.
"""
from __future__ import annotations

import math
from numbers import Real

import numpy as np

MAX_EDGE_STRETCH = 1.0
MAX_SECONDARY_MOTION_PCT = 50.0


class ClipOutOfBounds(ValueError):
    """A simulated clip that breaks a bound of this module (the message names it and the value)."""


def check_clip_bounds(transforms: np.ndarray, quality: dict) -> None:
    """Raise :class:`ClipOutOfBounds` unless the simulated clip is within the module's bounds.

    Args:
        transforms: (F, K, 7) the clip's stored transforms (quaternion w, x, y, z and translation, metres).
        quality: the clip's quality (:func:`mimicbench.datagen.apparel.quality.clip_quality` and the simulation's counts).

    Raises:
        ClipOutOfBounds: naming the bound, its value and the clip's value.
    """
    transforms = np.asarray(transforms)
    bad = int((~np.isfinite(transforms)).sum())
    if bad:
        raise ClipOutOfBounds(f"{bad} transform values are NaN or infinite; expected every stored value finite")
    for key, value in quality.items():
        if isinstance(value, Real) and not isinstance(value, bool) and not math.isfinite(float(value)):
            raise ClipOutOfBounds(f"quality {key} is {value}; expected every stored value finite")
    stretch = quality.get("max_edge_stretch")
    if stretch is not None and stretch > MAX_EDGE_STRETCH:
        raise ClipOutOfBounds(f"max_edge_stretch {stretch:.3g} is over the bound {MAX_EDGE_STRETCH:g} (an apparel "
                              f"edge {1 + stretch:.3g}x its rest length): the physics did not hold the chains "
                              f"together (check link_mass, stiffness and the other --params values)")
    moved = quality.get("secondary_motion_max_pct")
    if moved is not None and moved > MAX_SECONDARY_MOTION_PCT:
        raise ClipOutOfBounds(f"secondary_motion_max_pct {moved:.3g} is over the bound {MAX_SECONDARY_MOTION_PCT:g} "
                              f"(apparel {moved:.3g}% of the character's height away from where the body carries "
                              f"it): the apparel left the body (check link_mass and the other --params values)")


__all__ = ["MAX_EDGE_STRETCH", "MAX_SECONDARY_MOTION_PCT", "ClipOutOfBounds", "check_clip_bounds"]
