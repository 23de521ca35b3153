"""Characters as tensors for G and H, and the training examples of the transfer stage.

:class:`CharacterTensors` holds one character's rest mesh, skeleton, skin weights, skeleton
features and the fixed vertex subset the shape encoder E reads. :func:`shape_tokens` is the one
place that calls E. The transfer stage trains on (source character, source pose, target
character) triples drawn from a dataset's characters and motions (:func:`read_transfer_pool`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mimicbench.baselines.mimicat.corr_data import keypoint_features, point_indices, rest_frame


@dataclass
class CharacterTensors:
    """One character ready for G and H (tensors on one device).

    Attributes:
        character_id: stable ID.
        vertices: (N, 3) rest vertices, metres.
        keypoints: (K, 3) rest joint heads.
        parents: (K,) numpy int parents.
        weight_indices, weight_values: (N, J) sparse skin weights.
        features: (K, KEYPOINT_FEATURES) skeleton features.
        points: (P,) long vertex indices read by E.
        centre: (3,) rest bounding-box centre; size: its largest side (metres).
        unit_keypoints: (K, 3) rest keypoints in the unit-height frame
            (:func:`mimicbench.geometry.mesh.normalize_unit_height`), for G's geometric term.
    """

    character_id: str
    vertices: torch.Tensor
    keypoints: torch.Tensor
    parents: np.ndarray
    weight_indices: torch.Tensor
    weight_values: torch.Tensor
    features: torch.Tensor
    points: torch.Tensor
    centre: torch.Tensor
    size: float
    unit_keypoints: torch.Tensor

    @classmethod
    def build(cls, character_id: str, vertices, keypoints, parents, weight_indices, weight_values, num_points: int,
              device="cpu") -> "CharacterTensors":
        """From arrays: (N, 3) vertices, (K, 3) keypoints, (K,) parents, (N, J) skin weights."""
        from mimicbench.geometry.mesh import normalize_unit_height

        v = np.asarray(vertices, np.float64)
        centre, size = rest_frame(v)
        dev = torch.device(device)
        return cls(character_id, torch.as_tensor(v, dtype=torch.float32, device=dev),
                   torch.tensor(np.asarray(keypoints, np.float64), dtype=torch.float32, device=dev),
                   np.asarray(parents, np.int64),
                   torch.tensor(np.asarray(weight_indices, np.int64), device=dev),
                   torch.tensor(np.asarray(weight_values, np.float32), device=dev),
                   torch.as_tensor(keypoint_features(keypoints, parents, v), device=dev),
                   torch.as_tensor(point_indices(len(v), num_points, character_id), device=dev),
                   torch.as_tensor(centre, dtype=torch.float32, device=dev), size,
                   torch.as_tensor(normalize_unit_height(keypoints, v), dtype=torch.float32, device=dev))

    @classmethod
    def of_rig(cls, rig, num_points: int, device="cpu") -> "CharacterTensors":
        """From a :class:`mimicbench.benchmark.request.Rig`."""
        return cls.build(rig.character_id, rig.vertices, rig.keypoints, rig.parents, rig.weights.indices,
                         rig.weights.values, num_points, device)

    @classmethod
    def of_record(cls, record, num_points: int, device="cpu") -> "CharacterTensors":
        """From a :class:`mimicbench.schemas.character.CharacterRecord`."""
        return cls.build(record.character_id, record.vertices, record.keypoints, record.parents,
                         record.weight_indices, record.weight_values, num_points, device)

    @property
    def num_keypoints(self) -> int:
        return len(self.parents)

    def normalised(self, vertices: torch.Tensor) -> torch.Tensor:
        """(P, 3) the E points of ``vertices`` (N, 3) (rest or posed) in this character's rest frame."""
        return (vertices[self.points] - self.centre) / self.size


def shape_tokens(encoder: torch.nn.Module, points: torch.Tensor) -> torch.Tensor:
    """Shape tokens (B, l_E, d) of normalised point clouds (B, P, 3) from the frozen encoder E."""
    return encoder(points)


def correspondence_inputs(src: list["CharacterTensors"], tgt: list["CharacterTensors"]) -> dict:
    """G's padded keypoint inputs for pairs of characters: ``kp_s``, ``mask_s``, ``kp_t``,
    ``mask_t`` (features and masks) and ``pos_s``, ``pos_t`` (unit-height rest keypoints)."""
    kp_s, mask_s = pad([s.features for s in src])
    kp_t, mask_t = pad([t.features for t in tgt])
    return {"kp_s": kp_s, "mask_s": mask_s, "kp_t": kp_t, "mask_t": mask_t,
            "pos_s": pad([s.unit_keypoints for s in src])[0], "pos_t": pad([t.unit_keypoints for t in tgt])[0]}


def pad(rows: list[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    """Stack (K_b, F) tensors into (B, K_max, F) zero-padded and a (B, K_max) bool mask (True: real)."""
    k = max(len(r) for r in rows)
    out = rows[0].new_zeros((len(rows), k) + tuple(rows[0].shape[1:]))
    mask = torch.zeros(len(rows), k, dtype=torch.bool, device=rows[0].device)
    for b, r in enumerate(rows):
        out[b, :len(r)] = r
        mask[b, :len(r)] = True
    return out, mask


def read_transfer_pool(dataset, split: str = "all") -> tuple[dict, dict]:
    """Characters with a mesh and their motions (each motion's transforms (F, K, 7)) by ID.

    Raises:
        ValueError: fewer than two characters with motions.
    """
    from mimicbench.schemas.shards import read_records

    chars = {c.character_id: c for c in read_records(dataset, "characters")
             if len(c.faces) and split in ("all", c.split)}
    motions: dict[str, list[np.ndarray]] = {}
    for m in read_records(dataset, "motions"):
        if m.character_id in chars and m.num_frames > 1:
            motions.setdefault(m.character_id, []).append(np.asarray(m.transforms, np.float32))
    if len(motions) < 2:
        raise ValueError(f"{dataset}: expected at least two characters with motions for the transfer stage, "
                         f"got {len(motions)}")
    return chars, motions
