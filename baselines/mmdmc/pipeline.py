"""The MMDMC forward pass at inference (Fig. 2): f_c's apparel mask, f_s's weights and LBS of the
body motion, f_d's apparel on the apparel vertices (the paper's joint refinement f_j is not part of
this model: docs/methods/mmdmc.md).

With the body-history f_d (the shipped one, :mod:`mimicbench.baselines.mmdmc.apparel_history`) there is no
rollout: each frame's apparel is predicted from the body's history in the request, and (config
``history_arap``) restored to its rest edge lengths by soft ARAP
(:mod:`mimicbench.baselines.mmdmc.apparel_arap`).

The rollout starts where a request starts: nothing is known of the apparel before it, so the
K = 3 history states are the body state of the request's first frame (the apparel at rest on the
body, not moving). The apparel protocol's requests start at the clip's first
frame, where the simulation started from rest too, or 90 frames before the scored window; the
apparel stage's training rollouts (``apparel_start="clip"``) start the same way through the same
function (:func:`rollout_from_rest`). Per-character results (mask, weights, EdgeConv neighbours)
are cached on the :class:`~mimicbench.baselines.mmdmc.data.Prepared` character.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mimicbench.baselines.mmdmc.apparel import HISTORY, apparel_components, component_neighbours
from mimicbench.baselines.mmdmc.apparel_arap import edges_among, restore
from mimicbench.baselines.mmdmc.apparel_history import BodyHistoryApparel, frame_bones, frame_rotations, rest_offsets
from mimicbench.baselines.mmdmc.body import skin
from mimicbench.baselines.mmdmc.chain_attachment import attached_weights, prepared_attachment
from mimicbench.baselines.mmdmc.data import Prepared
from mimicbench.baselines.mmdmc.segmentation import segmenter_inputs
from mimicbench.baselines.mmdmc.weight_smoothing import diffuse_weights, smooth_weights
from mimicbench.geometry.mesh import mesh_pieces


@dataclass
class Modules:
    """Trained modules (any may be None when a variant does not use it)."""

    seg: torch.nn.Module | None
    body: torch.nn.Module
    apparel: torch.nn.Module | None
    knn: int = 8
    threshold: float = 0.5
    apparel_skinning: str = "fs"
    mask_by_piece: bool = False
    weight_smoothing: int = 0
    weight_smoothing_radius: float = 0.0


def device_of(module: torch.nn.Module) -> torch.device:
    return next(module.parameters()).device


@torch.no_grad()
def apparel_probability(seg: torch.nn.Module, prep: Prepared, by_piece: bool = False) -> np.ndarray:
    """(N,) float32 f_c's apparel probability of every vertex (cached).

    With ``by_piece`` (ours, config ``mask_by_piece``) each vertex gets the mean probability of its
    mesh piece (connected along face edges): a garment or a lock of hair modelled as its own piece
    is then wholly apparel or wholly body, so f_c's stray vertices no longer tear it where the
    apparel's skinning switches. On a validation zoo (seed 303; zoo apparel is always its own piece)
    f_c's mask went from 94-96% of vertices right to 98-100%. A garment welded to the body takes the
    body's piece's vote, so leave it off for such meshes.
    """
    key = ("prob", id(seg), by_piece)
    if key not in prep.cache:
        x = torch.as_tensor(segmenter_inputs(prep, getattr(seg, "channels", 3)), device=device_of(seg))[None]
        p = torch.sigmoid(seg(x))[0].cpu().numpy()
        if by_piece:
            pieces = mesh_pieces(prep.faces, len(p))
            p = (np.bincount(pieces, p) / np.bincount(pieces))[pieces].astype(np.float32)
        prep.cache[key] = p
    return prep.cache[key]


def uses_piece_prior(body: torch.nn.Module) -> bool:
    """Whether f_s scores with the piece prior (config ``body_prior="piece"``)."""
    return getattr(body, "prior", "bone") == "piece"


@torch.no_grad()
def skinning_weights(body: torch.nn.Module, prep: Prepared) -> torch.Tensor:
    """(N, Kb) f_s's weights over the body joints (cached)."""
    key = ("weights", id(body))
    if key not in prep.cache:
        dev = device_of(body)
        piece = {"piece": torch.as_tensor(prep.prior, device=dev)[None]} if uses_piece_prior(body) else {}
        prep.cache[key] = body(torch.as_tensor(prep.rest_norm, device=dev)[None],
                               torch.as_tensor(prep.joints_norm, device=dev)[None],
                               torch.as_tensor(prep.geo, device=dev)[None],
                               torch.as_tensor(prep.bone, device=dev)[None], **piece)[0]
    return prep.cache[key]


def mesh_weights(body: torch.nn.Module, prep: Prepared, mask: np.ndarray | None, apparel_skinning: str = "fs",
                 smoothing: int = 0, radius: float = 0.0) -> torch.Tensor:
    """(N, Kb) weights the body states are skinned with (cached): f_s's, with the vertices of ``mask``
    (N,) bool (None: no apparel path, as in the body-only variant) moved onto the body bone their
    apparel chain hangs from when ``apparel_skinning="attachment"``
    (:mod:`mimicbench.baselines.mmdmc.chain_attachment`; ``"fs"`` keeps f_s's), then smoothed along the mesh
    ``smoothing`` iterations and then diffused over ``radius`` (a share of the height; both in
    :mod:`mimicbench.baselines.mmdmc.weight_smoothing`), so the seams between body and apparel skinning are
    smoothed too. With f_s's ``piece`` prior, vertices outside ``mask`` whose piece the prior wraps
    keep f_s's weights unsmoothed."""
    if apparel_skinning not in ("fs", "attachment"):
        raise ValueError(f"apparel_skinning: expected 'fs' or 'attachment', got {apparel_skinning!r}")
    w = skinning_weights(body, prep)
    mask = None if mask is None else np.asarray(mask, bool)
    if (mask is None or apparel_skinning == "fs") and not smoothing and not radius:
        return w
    key = ("mesh_weights", id(body), None if mask is None else mask.tobytes(), apparel_skinning, smoothing, radius)
    if key not in prep.cache:
        out = w.cpu().numpy()
        if mask is not None and apparel_skinning == "attachment":
            out = attached_weights(out, mask, prepared_attachment(prep)[0])
        raw = out
        out = smooth_weights(out, prep.edges, smoothing)
        out = diffuse_weights(out, prep.rest_norm, prep.faces, radius)
        if uses_piece_prior(body):
            # a piece the prior wraps is smooth already (pieces exchange no weight when diffused)
            keep = ~np.isnan(prep.prior[:, 0]) if mask is None else ~np.isnan(prep.prior[:, 0]) & ~mask
            out[keep] = raw[keep]
        prep.cache[key] = torch.as_tensor(out, dtype=w.dtype, device=w.device)
    return prep.cache[key]


def body_states(prep: Prepared, weights: torch.Tensor, transforms) -> torch.Tensor:
    """(F, N, 3) unit-height frame: LBS of the rest mesh with ``weights`` (N, Kb) and the body bones of
    ``transforms`` (F, K, 7)."""
    dev = weights.device
    t = torch.as_tensor(np.asarray(transforms, np.float32)[:, prep.body], device=dev)
    posed = skin(torch.as_tensor(prep.rest, device=dev), torch.as_tensor(prep.keypoints[prep.body], device=dev),
                 weights, t)
    return to_unit(prep, posed)


def to_unit(prep: Prepared, metres: torch.Tensor) -> torch.Tensor:
    c = torch.as_tensor(prep.centre, dtype=metres.dtype, device=metres.device)
    return (metres - c) / prep.height


def from_unit(prep: Prepared, unit: torch.Tensor) -> torch.Tensor:
    c = torch.as_tensor(prep.centre, dtype=unit.dtype, device=unit.device)
    return unit * prep.height + c


def apparel_layout(prep: Prepared, mask: np.ndarray, knn: int) -> tuple[np.ndarray, np.ndarray]:
    """Apparel vertex indices (A,) and their EdgeConv neighbours (A, knn) (local indices, same component)."""
    mask = np.asarray(mask, bool)
    key = ("layout", mask.tobytes(), knn)
    if key not in prep.cache:
        idx = np.flatnonzero(mask)
        labels = apparel_components(prep.faces, mask)
        prep.cache[key] = (idx, component_neighbours(prep.rest[idx], labels, knn))
    return prep.cache[key]


def rest_start(body: torch.Tensor, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The inputs of a rollout started at rest on the body at its first frame (how every request
    starts): nothing is known of the apparel before it, so the K = 3 history states are the first
    body state, not moving, and the frames before it repeat its body state and joints.

    Args:
        body: (B, F, A, 3) body states of the apparel vertices, frames 0..F-1 (unit-height frame).
        joints: (B, F, J, 3) posed body joints, frames 0..F-1.

    Returns:
        ``history`` (B, 3, A, 3), ``body`` (B, F+1, A, 3) of frames -1..F-1 and ``joints`` (B, F+3, J, 3)
        of frames -3..F-1, as :meth:`~mimicbench.baselines.mmdmc.apparel.ApparelDynamics.rollout` reads them.
    """
    history = body[:, :1].expand(-1, HISTORY, -1, -1)
    body_seq = torch.cat([body[:, :1], body], 1)
    joint_seq = torch.cat([joints[:, :1].expand(-1, HISTORY, -1, -1), joints], 1)
    return history, body_seq, joint_seq


def rollout_from_rest(dyn: torch.nn.Module, body: torch.Tensor, rest: torch.Tensor, joints: torch.Tensor,
                      neighbours: torch.Tensor, truncate: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """f_d rolled out from rest on the body at frame 0 (:func:`rest_start`): states and displacements,
    each (B, F, A, 3), unit-height frame. Inference (:func:`rollout_from_body`) and the apparel stage's
    from-rest rollouts (``apparel_start="clip"``, :mod:`mimicbench.baselines.mmdmc.training`) both call this, so
    training rolls out exactly as a request is answered.

    Args:
        body: (B, F, A, 3) body states of the apparel vertices; rest: (B, A, 3) their rest positions;
        joints: (B, F, J, 3) posed body joints; neighbours: (A, k) EdgeConv neighbours.
        truncate: truncated backpropagation every that many steps (0: none; values unchanged).
    """
    history, body_seq, joint_seq = rest_start(body, joints)
    return dyn.rollout(history, body_seq, rest, joint_seq, neighbours, truncate)


@torch.no_grad()
def rollout_from_body(dyn: torch.nn.Module, prep: Prepared, body: torch.Tensor, joints: torch.Tensor,
                      idx: np.ndarray, neighbours: np.ndarray) -> torch.Tensor:
    """Apparel states (F, A, 3) over a window whose body states are (F, N, 3) and posed body joints
    (F, Kb, 3) (unit-height frame), started from the first frame's body state at rest
    (:func:`rollout_from_rest`)."""
    dev = body.device
    sb = body[:, torch.as_tensor(idx, device=dev)]  # (F, A, 3)
    rest = torch.as_tensor(prep.rest_norm[idx], device=dev)[None]
    states, _ = rollout_from_rest(dyn, sb[None], rest, joints[None], torch.as_tensor(neighbours, device=dev))
    return states[0]


def history_inputs(prep: Prepared, idx: np.ndarray, weights: torch.Tensor, transforms) -> tuple[torch.Tensor, torch.Tensor]:
    """The body-history f_d's per-vertex frame inputs of the vertices ``idx`` (A,) skinned with
    ``weights`` (N, Kb), for transforms (F, K, 7): each vertex's frame rotations (F, A, 3, 3)
    (:func:`~mimicbench.baselines.mmdmc.apparel_history.frame_rotations`) and its rest offset (A, 3) in the
    unit-height frame (:func:`~mimicbench.baselines.mmdmc.apparel_history.rest_offsets`), on ``weights``' device.
    Training batches and requests both read them here."""
    dev = weights.device
    bones, fw = frame_bones(weights[torch.as_tensor(idx, device=dev)].cpu().numpy())
    t = torch.as_tensor(np.asarray(transforms, np.float32)[:, prep.body], device=dev)  # (F, Kb, 7)
    rot = frame_rotations(t, torch.as_tensor(bones, device=dev), torch.as_tensor(fw, device=dev))
    rest_offset = rest_offsets(prep.rest[idx], prep.keypoints[prep.body], bones, fw) / prep.height
    return rot, torch.as_tensor(rest_offset, dtype=torch.float32, device=dev)


@torch.no_grad()
def apparel_from_body(dyn: torch.nn.Module, prep: Prepared, body: torch.Tensor, transforms, weights: torch.Tensor,
                      idx: np.ndarray, neighbours: np.ndarray) -> torch.Tensor:
    """Apparel states (F, A, 3) (unit-height frame) of the vertices ``idx`` over a request whose body
    states are (F, N, 3), skinned with ``weights`` (N, Kb), for transforms (F, K, 7): f_d's rollout from
    rest (:func:`rollout_from_body`) or, for the body-history model, its prediction from the history
    of each vertex's frame (:mod:`mimicbench.baselines.mmdmc.apparel_history`)."""
    dev = body.device
    if isinstance(dyn, BodyHistoryApparel):
        rot, rest_offset = history_inputs(prep, idx, weights, transforms)
        states, _ = dyn.states(body[None, :, torch.as_tensor(idx, device=dev)], rot[None], rest_offset[None],
                               neighbours=torch.as_tensor(neighbours, device=dev))
        if dyn.arap > 0:
            key = ("apparel_edges", idx.tobytes())  # the mesh edges among the apparel, once per character and mask
            if key not in prep.cache:
                prep.cache[key] = edges_among(prep.edges, idx)
            kept = restore(states[0].cpu().numpy(), prep.rest_norm[idx], prep.cache[key], dyn.arap,
                           dyn.arap_iterations)
            return torch.as_tensor(kept, dtype=states.dtype, device=dev)
        return states[0]
    joints = to_unit(prep, torch.as_tensor(np.asarray(transforms, np.float32)[:, prep.body, 4:], device=dev))
    return rollout_from_body(dyn, prep, body, joints, idx, neighbours)


VARIANTS = ("full", "no_apparel", "body_only")


@torch.no_grad()
def predict(modules: Modules, prep: Prepared, transforms, variant: str = "full",
            gt_mask: np.ndarray | None = None) -> np.ndarray:
    """Posed vertices (F, N, 3) float32, metres, of a window of transforms (F, K, 7).

    Args:
        variant: ``full`` (body + apparel), ``no_apparel`` (the full model with f_d's displacement
            zero: apparel vertices stay where f_s's skinning with the same mask puts them), ``body_only`` (the
            body module alone, apparel skinned to body joints as f_s scores them).
        gt_mask: (N,) bool apparel mask to use instead of f_c's (the ``GT Mask`` ablation).
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {', '.join(map(repr, VARIANTS))}, got {variant!r}")
    if variant == "body_only":
        w = mesh_weights(modules.body, prep, None, smoothing=modules.weight_smoothing,
                         radius=modules.weight_smoothing_radius)
        return from_unit(prep, body_states(prep, w, transforms)).cpu().numpy().astype(np.float32)
    prob = apparel_probability(modules.seg, prep, modules.mask_by_piece)
    mask = prob > modules.threshold if gt_mask is None else np.asarray(gt_mask, bool)
    w = mesh_weights(modules.body, prep, mask, modules.apparel_skinning, modules.weight_smoothing,
                     modules.weight_smoothing_radius)
    s = body_states(prep, w, transforms)  # (F, N, 3)
    y = s.clone()
    if mask.any() and variant != "no_apparel":
        idx, nb = apparel_layout(prep, mask, modules.knn)
        y[:, torch.as_tensor(idx, device=s.device)] = apparel_from_body(modules.apparel, prep, s, transforms, w, idx, nb)
    return from_unit(prep, y).cpu().numpy().astype(np.float32)
