"""MikuMikuDance characters and motions: bounded PMX/PMD/VMD readers, conversion to the dataset's
frame and records, physics (rigid bodies, joints) as records, apparel from physics.

One concept a file: :mod:`.binary` (bounded reading), :mod:`.pmx`, :mod:`.pmd`, :mod:`.vmd`
(readers), :mod:`.model` (the file's contents), :mod:`.frame` (MMD -> dataset frame),
:mod:`.names` (English canonical names), :mod:`.records` (character records), :mod:`.apparel`,
:mod:`.physics` (rigid-body/joint records), :mod:`.bezier` (keyframe curves), :mod:`.pose`
(MMD's bone evaluation order), :mod:`.grant` (付与), :mod:`.ik` (CCD), :mod:`.motion` (a VMD
on a model as a motion record), :mod:`.ingest` (the ``datagen ingest`` path).
"""
from __future__ import annotations

MODEL_SUFFIXES = (".pmx", ".pmd")
MOTION_SUFFIXES = (".vmd",)


def is_mmd_file(path) -> bool:
    """True for .pmx, .pmd and .vmd files (by suffix, case-insensitive)."""
    from pathlib import Path

    return Path(path).suffix.lower() in MODEL_SUFFIXES + MOTION_SUFFIXES


def read_model(path):
    """Read a .pmx or .pmd file as :class:`~mimicbench.datagen.mmd.model.MMDModel` (by suffix)."""
    from pathlib import Path

    if Path(path).suffix.lower() == ".pmd":
        from mimicbench.datagen.mmd.pmd import read_pmd

        return read_pmd(path)
    from mimicbench.datagen.mmd.pmx import read_pmx

    return read_pmx(path)
