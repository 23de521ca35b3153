"""Resample characters to a target face count (5,000 by default) and re-skin them.

:mod:`.clean` checks and cleans, :mod:`.simplify` decimates (fast-simplification by default, or
pymeshlab) or refines and says which piece of the input each new vertex came from,
:mod:`.closest_point` (libigl's AABB tree), :mod:`.pieces` (the closest point on the vertex's own
piece) and :mod:`.reskin` carry the weights over by barycentric interpolation, :mod:`.quality`
measures Hausdorff distance and skinning transfer error, :mod:`.character` does one character and
:mod:`.stage` a whole dataset.

Known limit: the zoo's snakes (reptile template, even variants) are chains of 12-60 overlapping
capsules, each hiding a pair of caps inside the body; at 5,000 faces those interior caps keep
the Hausdorff distance at 2-4% of the snake's height (its diameter), by Blender's Decimate too.
A body made of one closed surface (a boolean union of the capsules, then a remesh to remove
the union's slivers) would lift it; that belongs to the zoo.
"""
from __future__ import annotations

# the stage's face-count limits (checked by the stage, offered by the CLI); here so neither imports the other
MIN_FACES = 100  # below this a character mesh is no longer a character; simplifiers stop early
MAX_FACES = 1_000_000  # above this refinement would need gigabytes per character
# in the stage's fingerprint, so a re-run redoes rows an older resample made; CHANGELOG.md says what each
# version changed
RESAMPLE_VERSION = "4"
