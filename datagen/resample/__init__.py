"""Resample characters to a target face count (5,000 by default) and re-skin them.

:mod:`.clean` checks and cleans, :mod:`.simplify` decimates (pymeshlab or fast-simplification)
or refines, :mod:`.closest_point` and :mod:`.reskin` carry the weights over by barycentric
interpolation, :mod:`.quality` measures Hausdorff distance and skinning transfer error,
:mod:`.character` does one character and :mod:`.stage` a whole dataset.
"""
from __future__ import annotations

import importlib

_LAZY = {
    "resample_character": "datagen.resample.character",
    "resample_dataset": "datagen.resample.stage",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """Import the public functions on first use, so the CLI starts fast."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
