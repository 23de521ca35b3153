"""Resample one character: clean, reach the target face count, reskin, measure."""
from __future__ import annotations

import dataclasses

import numpy as np

from mimicbench.datagen.resample.clean import BadMesh, clean_mesh
from mimicbench.datagen.resample.closest_point import closest_points
from mimicbench.datagen.resample.pieces import own_piece_points
from mimicbench.datagen.resample.quality import hausdorff_percent, transfer_error_percent
from mimicbench.datagen.resample.reskin import interpolate_mask, interpolate_weights
from mimicbench.datagen.resample.simplify import resample_to
from mimicbench.schemas.character import CharacterRecord
from mimicbench.schemas.validate import parents_problem

SAMPLED_FRAMES = 8


def sample_frames(motions, count: int = SAMPLED_FRAMES) -> np.ndarray:
    """(F, K, 7) evenly spaced frames across a character's motions (deterministic)."""
    frames = [m.transforms[i] for m in motions for i in np.linspace(0, m.num_frames - 1, 3).astype(int)]
    if not frames:
        return np.zeros((0, 0, 7), np.float32)
    idx = np.linspace(0, len(frames) - 1, min(count, len(frames))).astype(int)
    return np.stack([frames[i] for i in idx])


def resample_character(record: CharacterRecord, motions: list, faces: int = 5000,
                       backend: str = "fast") -> CharacterRecord:
    """A copy of ``record`` with its mesh resampled to ``faces`` faces and weights re-skinned.

    Keypoints, bone names, parents, roles and motions are untouched. ``meta["resample"]`` records
    the input and output face counts, subdivision rounds, what cleaning removed, the symmetric
    Hausdorff distance and the skinning transfer error (both in percent of height), when the
    resampled mesh had short edges or zero-area faces to weld away, ``weld``: what
    :func:`mimicbench.datagen.resample.clean.weld_short_edges` removed and the face count decimation aimed at,
    and, when some new vertices lie closest to another piece than the one they came from,
    ``own_piece_vertices``: how many (they take their weights from their own piece,
    :func:`mimicbench.datagen.resample.pieces.own_piece_points`).

    Raises:
        mimicbench.datagen.resample.clean.BadMesh: the input mesh cannot be resampled (the reason says why): a
            skeleton out of the format's order (a cycle), a rest mesh with no height, a quality value
            that is not finite.
    """
    cycle = parents_problem(record.parents)
    if cycle:
        raise BadMesh(f"skeleton out of order: {cycle}")
    clean = clean_mesh(record.vertices, record.faces, record.weights, record.apparel_vertex_mask)
    rest_height = float(np.ptp(np.asarray(clean.vertices, np.float64)[:, 1])) if len(clean.vertices) else 0.0
    if not (np.isfinite(rest_height) and rest_height > 0):
        raise BadMesh(f"the rest mesh has no height (Y extent {rest_height:g}): the resample's quality (percent "
                      f"of height) and every score divide by it")
    welded: dict = {}
    new_v, new_f, refined, pieces = resample_to(clean.vertices, clean.faces, faces, backend, report=welded)
    anywhere = closest_points(clean.vertices, clean.faces, new_v)
    surface = own_piece_points(clean.vertices, clean.faces, new_v, pieces, anywhere)
    weights = interpolate_weights(clean.weights, clean.faces, surface)
    apparel = interpolate_mask(clean.apparel, clean.faces, surface)
    height = float(np.ptp(clean.vertices[:, 1]))
    frames = sample_frames(motions)
    quality = {
        "faces_in": int(len(record.faces)), "faces_out": int(len(new_f)), "backend": backend,
        "subdivisions": int(refined), "clean": clean.report,
        "hausdorff_pct": hausdorff_percent(clean.vertices, clean.faces, new_v, new_f, height, anywhere),
        "transfer_error_pct": transfer_error_percent(clean.vertices, clean.faces, clean.weights, new_v, weights,
                                                     record.keypoints, surface, frames, height),
        "frames_measured": int(len(frames)),
    }
    for key in ("hausdorff_pct", "transfer_error_pct"):
        if not np.isfinite(quality[key]):
            raise BadMesh(f"{key} is {quality[key]}: expected a finite percent of the height {height:g} m")
    if welded["welded_vertices"] or welded["zero_area_faces"]:
        quality["weld"] = welded  # only when the resampled mesh needed it, so clean meshes keep their bytes
    moved = int((surface.faces != anywhere.faces).sum())
    if moved:
        quality["own_piece_vertices"] = moved  # likewise: only when a closest point moved to the vertex's own piece
    meta = dict(record.meta or {})
    meta["resample"] = quality
    return dataclasses.replace(
        record, vertices=new_v.astype(np.float32), faces=new_f.astype(np.int32),
        weight_indices=weights.indices, weight_values=weights.values, apparel_vertex_mask=apparel,
        height=float(np.ptp(new_v[:, 1])), meta=meta)
