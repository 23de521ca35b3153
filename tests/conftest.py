"""Shared test set-up: the torchvision shim, paths to the shared assets, toy characters."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")


def _torchvision_shim() -> None:
    """Let a CUDA build of torchvision import beside a CPU build of torch (this machine's pair).

    torchvision registers fake kernels for its C++ ops at import; with a CPU torch those op
    schemas do not exist and the import fails ("operator torchvision::nms does not exist"), which
    breaks open_clip and transformers. Defining the two schemas first lets the import succeed.
    A user's matching torch and torchvision never need this.
    """
    try:
        import torch
    except ImportError:  # pragma: no cover
        return
    try:
        import torchvision  # noqa: F401
        return
    except Exception:
        pass
    lib = torch.library.Library("torchvision", "DEF")
    for op in ("nms", "qnms"):
        try:
            lib.define(f"{op}(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")
        except RuntimeError:
            pass
    _torchvision_shim.lib = lib  # keep the library alive


_torchvision_shim()

REPO = Path(__file__).resolve().parents[1]
ASSETS = REPO.parent / "shared" / "assets"


@pytest.fixture(scope="session")
def assets_dir() -> Path:
    """``../shared/assets`` (read only; never copied into the repo)."""
    if not ASSETS.is_dir():
        pytest.fail(f"shared assets not found at {ASSETS}; tests expect ../shared/assets beside the repo")
    return ASSETS


@pytest.fixture
def tube():
    """A 4-bone tube character (see :func:`tests.toys.make_tube`)."""
    from tests.toys import make_tube

    return make_tube()


@pytest.fixture(scope="session")
def small_zoo(tmp_path_factory) -> Path:
    """A 14-character zoo (seed 0) shared by the tests of later stages; copy it before writing."""
    from mimicbench.datagen.zoo.dataset import build_zoo

    root = tmp_path_factory.mktemp("zoo") / "zoo14"
    build_zoo(root, 14, seed=0, progress=False)
    return root
