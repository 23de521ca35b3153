"""Let ``open_clip`` and ``sentence_transformers`` import beside a mismatched torchvision.

On a machine with a CPU build of torch and a CUDA build of torchvision (what the package
registry serves for torch 2.13.0 / torchvision 0.28.0 on Linux), ``import torchvision`` fails
with "operator torchvision::nms does not exist", because torchvision registers fake kernels for
C++ ops whose schemas only its CUDA library defines; transformers and open_clip then fail to
import too. mimicbench uses neither op. :func:`ensure_torchvision_importable` tries the import
and, only on that specific failure, defines the two missing op schemas so the import succeeds.
A matching torch/torchvision pair is left untouched.
"""
from __future__ import annotations

import sys

_MISSING_OPS = ("nms", "qnms")
_library = None


def ensure_torchvision_importable() -> None:
    """Import torchvision, defining its missing op schemas if (and only if) that is the failure."""
    global _library
    try:
        import torchvision  # noqa: F401
        return
    except ImportError:
        return  # not installed: the encoders that need it will say so
    except RuntimeError as exc:
        if "torchvision::" not in str(exc) or "does not exist" not in str(exc):
            raise
    import torch

    for name in [m for m in sys.modules if m == "torchvision" or m.startswith("torchvision.")]:
        del sys.modules[name]
    _library = torch.library.Library("torchvision", "DEF")
    for op in _MISSING_OPS:
        try:
            _library.define(f"{op}(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")
        except RuntimeError:
            pass  # already defined
    import torchvision  # noqa: F401,F811
