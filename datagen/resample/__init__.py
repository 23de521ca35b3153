"""Resample characters to a target face count (5,000 by default) and re-skin them.

:mod:`.clean` checks and cleans, :mod:`.simplify` decimates (pymeshlab or fast-simplification)
or refines, :mod:`.closest_point` and :mod:`.reskin` carry the weights over by barycentric
interpolation, :mod:`.quality` measures Hausdorff distance and skinning transfer error,
:mod:`.character` does one character and :mod:`.stage` a whole dataset.
"""
from datagen.resample.character import resample_character
from datagen.resample.stage import resample_dataset

__all__ = ["resample_character", "resample_dataset"]
