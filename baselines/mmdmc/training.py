"""The MMDMC reference's training stages for the shared trainer (``mimicbench train mmdmc``).

Stages, in order (Sec. 4.5 of the paper: segmentation and body trained independently, the rest
end to end on their outputs):

- ``seg``: f_c, binary cross entropy against the dataset's apparel vertex mask (inputs per
  ``seg_inputs``: positions, or positions and bone distances; :mod:`mimicbench.baselines.mmdmc.segmentation`).
- ``body``: f_s, L1 vertex (Eq. 8), edge length (Eq. 9) and weight smoothness (Eq. 10) against the
  body target (:mod:`mimicbench.baselines.mmdmc.data`), plus (ours, ``w_weights``) the L1 distance of f_s's
  weights to the body target's weights, a denser signal than the posed vertices (which say
  nothing of a bone that did not move). ``weights_on`` says which vertices that term averages
  over: ``"all"`` (the default, the shipped model's) or ``"body"``. Over all vertices the apparel
  vertices (a third to a half of a zoo character, their prior 1.6 of 2 away from the target)
  dominate it, and f_s learns their attachment bones at the body's cost (body weight error and
  PMD_b rise over the untrained prior); with ``"body"`` apparel vertices follow the body target
  through the vertex and edge terms alone. With ``seg_body_clips="kinematic"`` seg and body
  read every kinematic clip, so they can train on a zoo that was never simulated (more
  characters than the simulated set); the default reads the simulated pairs, as the shipped
  model did.
- ``apparel`` (needs seg, body): f_d rolled out on the apparel vertices f_c finds, from f_s's body
  states; L1 vertex, edge length (Eq. 14-15) and an L2 regulariser on the displacements. With
  ``apparel_start="clip"`` (opt-in; with ``bptt`` 0 a hair better than a zero displacement,
  docs/notes/mmdmc.md) every rollout starts as the simulation
  and a request of the apparel protocol do: at rest on the body at the clip's first frame (K = 3
  history states of the body at rest, :func:`mimicbench.baselines.mmdmc.pipeline.rest_start`), rolled out
  through the burn-in to the window's end (at most ``burn_in`` + ``scored_window`` frames; a longer
  clip rolls out from a random frame, scored only on its last ``scored_window`` frames, as a request
  that starts a full burn-in before its window is) by the same function inference calls
  (:func:`mimicbench.baselines.mmdmc.pipeline.rollout_from_rest`), with truncated backpropagation every ``bptt``
  steps (0: none). With ``apparel_start="window"`` (the default) a rollout is a window of
  ``window`` frames after K ground-truth states (Eq. 11, the paper's), a share ``rest_start`` of
  them restarted at rest on the body at the window, inside the clip: where the simulated apparel
  already lags the body, a target the rest-started rollout's inputs cannot reach.
  With ``apparel_skinning="attachment"`` the apparel vertices (f_c's mask,
  voted per mesh piece with ``mask_by_piece``) start from the body bone their chain hangs from
  (:mod:`mimicbench.baselines.mmdmc.chain_attachment`), the body target's own rule, rather than f_s's
  weights; ``weight_smoothing`` (edge hops) and ``weight_smoothing_radius`` (a distance) smooth
  f_s's weights along the mesh (:mod:`mimicbench.baselines.mmdmc.weight_smoothing`). All four are off by default (the first shipped
  model's settings) and read at inference from the stages' checkpoints.
  With ``apparel_model="body_history"`` (ours; the shipped f_d) f_d is
  :class:`mimicbench.baselines.mmdmc.apparel_history.BodyHistoryApparel`: each batch is a clip read from where a
  request of it starts, with each apparel vertex's frame rotations and rest offset; ``history_frames``
  of its scored frames are predicted, and the loss is vertex L1 plus ``w_stretch`` times the relative
  stretch of the apparel's mesh edges.

Each batch is built from the training dataset (``mimicbench datagen apparel`` output) with the
epoch's generator; a vertex subsample (``points``) stands in for the whole mesh in ``seg`` and
``body``, its rest-pose nearest neighbours for the mesh edges (``body_edge_loss="knn"``, the
default and every shipped f_s's: Eq. 9 there is about 1e-5 and does almost nothing). With
``body_edge_loss="mesh_stretch"`` the body subsample is drawn as the two ends of ``points // 2``
random mesh edges, and Eq. 9 becomes the mean relative stretch |l_pred / l_truth - 1| (what ELS
measures) on those real edges whose two ends the weights term covers.

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree

from mimicbench.baselines.mmdmc.apparel import HISTORY, ApparelDynamics, component_neighbours, apparel_components
from mimicbench.baselines.mmdmc.apparel_arap import ITERATIONS, edges_among
from mimicbench.baselines.mmdmc.apparel_history import BodyHistoryApparel
from mimicbench.baselines.mmdmc.body import BodySkinning, skin
from mimicbench.baselines.mmdmc.config import CONFIGS
from mimicbench.baselines.mmdmc.data import Prepared, TrainingData, body_target_weights, posed
from mimicbench.baselines.mmdmc.losses import edge_length, edge_stretch, l2_regulariser, vertex_l1, weight_smoothness, weighted_total
from mimicbench.baselines.mmdmc.pipeline import (apparel_probability, history_inputs, mesh_weights, rollout_from_rest,
                                      to_unit)
from mimicbench.baselines.mmdmc.segmentation import SEG_INPUTS, ApparelSegmenter, segmenter_inputs
from mimicbench.training.batching import rank_batches
from mimicbench.training.registry import make_trainable
from mimicbench.training.stage import StageContext, TrainStage

_DATA: dict = {}


def training_data(config: dict, context: StageContext, simulated: bool = True) -> TrainingData:
    """The dataset's prepared characters and clips, loaded once per process (``simulated=False``:
    every kinematic clip, no simulation needed)."""
    key = (str(context.dataset), config.get("split", "all"), config["bridge_neighbours"], simulated)
    if key not in _DATA:
        _DATA[key] = TrainingData.load(context.dataset, config.get("split", "all"), config["bridge_neighbours"],
                                       simulated)
    return _DATA[key]


def seg_body_simulated(config: dict) -> bool:
    """Whether seg and body read the simulated clip pairs (``seg_body_clips="simulated"``, the default
    and the shipped model's) or every kinematic clip (``"kinematic"``: they need no simulation)."""
    mode = config.get("seg_body_clips", "simulated")
    if mode not in ("simulated", "kinematic"):
        raise ValueError(f"seg_body_clips: expected 'simulated' or 'kinematic', got {mode!r}")
    return mode == "simulated"


def setting(config: dict, stage: str, key: str):
    """``config[stage][key]`` when the stage overrides it, else ``config[key]`` (as the trainer reads them)."""
    sub = config.get(stage)
    return sub[key] if isinstance(sub, dict) and key in sub else config[key]


def _draws(config: dict, context: StageContext, rng: np.random.Generator, n_choices: int, stage: str):
    """This rank's batches of one epoch: lists of draws in [0, n_choices), with per-draw seeds."""
    n = setting(config, stage, "batches_per_epoch") * config["batch_size"]
    picks = rng.integers(0, n_choices, size=n)
    seeds = rng.integers(0, 2**31 - 1, size=n)
    for idx in rank_batches(n, config["batch_size"], rng, context.rank, context.world_size):
        yield [(int(picks[i]), int(seeds[i])) for i in idx]


def _subsample(n: int, points: int, rng: np.random.Generator) -> np.ndarray:
    return np.sort(rng.choice(n, size=min(points, n), replace=False))


def _knn_edges(points: np.ndarray, k: int) -> np.ndarray:
    """(P*k, 2) int64 pairs of each point with its k nearest others."""
    _, nn_ = cKDTree(points).query(points, k=k + 1)
    return np.stack([np.repeat(np.arange(len(points)), k), nn_[:, 1:].reshape(-1)], 1).astype(np.int64)


# ---- seg -------------------------------------------------------------------------------------

def seg_channels(config: dict) -> int:
    """f_c's input channels for the config's ``seg_inputs`` (absent in the first shipped model's: positions)."""
    mode = config.get("seg_inputs", "positions")
    if mode not in SEG_INPUTS:
        raise ValueError(f"seg_inputs: expected one of {sorted(SEG_INPUTS)}, got {mode!r}")
    return SEG_INPUTS[mode]


def build_seg(config: dict, context: StageContext | None = None) -> torch.nn.Module:
    return ApparelSegmenter(config["seg_hidden"], seg_channels(config))


def batches_seg(config: dict, context: StageContext, rng: np.random.Generator):
    data = training_data(config, context, seg_body_simulated(config))
    ids = sorted(data.characters)
    for batch in _draws(config, context, rng, len(ids), "seg"):
        pts, labels = [], []
        for pick, seed in batch:
            r = np.random.default_rng(seed)
            c = data.characters[ids[pick]]
            rows = _subsample(len(c.rest), config["points"], r)
            scale = r.uniform(0.9, 1.1)
            pts.append(segmenter_inputs(c, seg_channels(config))[rows] * scale)
            labels.append(c.apparel[rows])
        yield {"points": np.stack(pts).astype(np.float32), "labels": np.stack(labels).astype(np.float32)}


def loss_seg(module, batch, context) -> dict:
    logits = module(batch["points"])
    bce = torch.nn.functional.binary_cross_entropy_with_logits(logits, batch["labels"])
    accuracy = ((logits > 0).float() == batch["labels"]).float().mean().detach()
    return {"total": bce, "bce": bce, "accuracy": accuracy}


# ---- body ------------------------------------------------------------------------------------

def build_body(config: dict, context: StageContext | None = None) -> torch.nn.Module:
    return BodySkinning(config["body_hidden"], prior=config.get("body_prior", "bone"))


BODY_EDGE_LOSSES = ("knn", "mesh_stretch")


def config_choice(config: dict, key: str, choices: tuple[str, ...], default: str) -> str:
    """``config[key]`` (``default`` where an older config lacks it), which must be one of ``choices``."""
    mode = config.get(key, default)
    if mode not in choices:
        raise ValueError(f"{key}: expected one of {choices}, got {mode!r}")
    return mode


def body_edge_loss(config: dict) -> str:
    """The config's ``body_edge_loss`` (absent in configs up to v5: "knn")."""
    return config_choice(config, "body_edge_loss", BODY_EDGE_LOSSES, "knn")


def _mesh_edge_subsample(n: int, edges: np.ndarray, points: int, r: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A vertex subsample made of the ends of ``points // 2`` random mesh edges (topped up with random
    other vertices to ``points``): (P,) sorted vertex rows and those (points // 2, 2) edges as row indices."""
    picks = edges[r.choice(len(edges), size=min(points // 2, len(edges)), replace=False)]
    rows = np.unique(picks)
    short = min(points, n) - len(rows)
    if short > 0:
        rest = np.setdiff1d(np.arange(n), rows)
        rows = np.sort(np.r_[rows, r.choice(rest, size=short, replace=False)])
    return rows, np.searchsorted(rows, picks).astype(np.int64)


def _body_item(c: Prepared, transforms: np.ndarray, config: dict, r: np.random.Generator) -> dict:
    if body_edge_loss(config) == "mesh_stretch":
        rows, edges = _mesh_edge_subsample(len(c.rest), c.edges, setting(config, "body", "points"), r)
    else:
        rows = _subsample(len(c.rest), setting(config, "body", "points"), r)
        edges = _knn_edges(c.rest[rows], config["neighbours_loss"])
    bw = body_target_weights(c)[rows]
    t_body = transforms[c.body]
    target = skin(torch.as_tensor(c.rest[rows]), torch.as_tensor(c.keypoints[c.body]), torch.as_tensor(bw),
                  torch.as_tensor(t_body)).numpy()
    return {"points": c.rest_norm[rows], "joints": c.joints_norm, "geo": c.geo[rows], "bone": c.bone[rows], "rest": c.rest[rows],
            "rest_joints": c.keypoints[c.body], "transforms": t_body, "target": c.norm(target),
            "centre": c.centre.astype(np.float32), "height": np.float32(c.height), "target_weights": bw,
            "apparel": c.apparel[rows], "edges": edges}


def batches_body(config: dict, context: StageContext, rng: np.random.Generator):
    data = training_data(config, context, seg_body_simulated(config))
    frames = [(i, f) for i, clip in enumerate(data.clips) for f in range(clip.frames)]
    for batch in _draws(config, context, rng, len(frames), "body"):
        items = []
        for pick, seed in batch:
            ci, f = frames[pick]
            clip = data.clips[ci]
            items.append(_body_item(data.characters[clip.character_id], clip.kinematic[f], config,
                                    np.random.default_rng(seed)))
        kmax = max(len(it["joints"]) for it in items)
        out = {k: [] for k in items[0]}
        out["joint_mask"] = []
        for it in items:
            pad = kmax - len(it["joints"])
            ident = np.tile(np.array([1, 0, 0, 0, 0, 0, 0], np.float32), (pad, 1))
            out["joint_mask"].append(np.r_[np.ones(len(it["joints"]), bool), np.zeros(pad, bool)])
            for k, v in it.items():
                if k == "target_weights":
                    v = np.concatenate([v, np.zeros((len(v), pad), np.float32)], 1)
                elif k in ("joints", "rest_joints"):
                    v = np.concatenate([v, np.zeros((pad, 3), np.float32)])
                elif k in ("geo", "bone"):
                    v = np.concatenate([v, np.ones((len(v), pad), np.float32)], 1)
                elif k == "transforms":
                    v = np.concatenate([v, ident])
                out[k].append(v)
        yield {k: np.stack(v) for k, v in out.items()}


def loss_body(module, batch, context) -> dict:
    w = module(batch["points"], batch["joints"], batch["geo"], batch["bone"], batch["joint_mask"])
    mode = context.config.get("weights_on", "all")
    if mode not in ("body", "all"):
        raise ValueError(f"weights_on: expected 'body' or 'all', got {mode!r}")
    on = torch.ones_like(batch["apparel"], dtype=w.dtype) if mode == "all" else (~batch["apparel"].bool()).to(w.dtype)
    terms = {"vertex": 0.0, "edge": 0.0, "smooth": 0.0,
             "weights": ((w - batch["target_weights"]).abs().sum(-1) * on).sum() / on.sum().clamp_min(1.0)}
    b = len(w)
    stretch = body_edge_loss(context.config) == "mesh_stretch"
    for i in range(b):
        pred = (skin(batch["rest"][i], batch["rest_joints"][i], w[i], batch["transforms"][i]) - batch["centre"][i]) \
            / batch["height"][i]
        terms["vertex"] = terms["vertex"] + vertex_l1(pred, batch["target"][i]) / b
        if stretch:  # on the edges whose two ends the weights term covers (weights_on)
            e = batch["edges"][i]
            e = e[(on[i][e[:, 0]] > 0) & (on[i][e[:, 1]] > 0)]
            terms["edge"] = terms["edge"] + edge_stretch(pred, batch["target"][i], e) / b
        else:
            terms["edge"] = terms["edge"] + edge_length(pred, batch["target"][i], batch["edges"][i]) / b
        terms["smooth"] = terms["smooth"] + weight_smoothness(w[i], batch["edges"][i]) / b
    return weighted_total(terms, context.config)


# ---- apparel ---------------------------------------------------------------------------------

APPAREL_MODELS = ("rollout", "body_history")


def apparel_model(config: dict) -> str:
    """The config's ``apparel_model`` (``"rollout"`` in a config without the key)."""
    return config_choice(config, "apparel_model", APPAREL_MODELS, "rollout")


def build_apparel(config: dict, context: StageContext | None = None) -> torch.nn.Module:
    if apparel_model(config) == "body_history":
        return BodyHistoryApparel(config.get("history_hidden", 256), config.get("history_layers", 3),
                                  int(config.get("history_smoothing", 0)), float(config.get("history_arap", 0.0)),
                                  int(config.get("history_arap_iterations", ITERATIONS)),
                                  bool(config.get("history_still_zero", False)))
    return ApparelDynamics(config["apparel_hidden"], config["code"])


def _predicted_mask(c: Prepared, context: StageContext, config: dict) -> np.ndarray:
    return apparel_probability(context.frozen["seg"], c, config.get("mask_by_piece", False)) > config["threshold"]


def _mask_components(c: Prepared, mask: np.ndarray) -> np.ndarray:
    """(A,) component labels of the vertices of ``mask`` (:func:`apparel_components`, cached on ``c``)."""
    key = ("components", mask.tobytes())
    if key not in c.cache:
        c.cache[key] = apparel_components(c.faces, mask)
    return c.cache[key]


def _pick_components(c: Prepared, mask: np.ndarray, cap: int, r: np.random.Generator) -> np.ndarray:
    """Apparel vertex indices: every one, or whole components drawn at random until ``cap``."""
    idx = np.flatnonzero(mask)
    if cap <= 0 or len(idx) <= cap:
        return idx
    labels = _mask_components(c, mask)
    keep, total = [], 0
    for lab in r.permutation(np.unique(labels)):
        members = idx[labels == lab]
        if keep and total + len(members) > cap:
            continue
        keep.append(members)
        total += len(members)
    return np.sort(np.concatenate(keep))


def _windows(data: TrainingData, first: int, length: int) -> list[tuple[int, int]]:
    return [(i, t0) for i, clip in enumerate(data.clips) for t0 in range(first, clip.frames - length + 1)]


APPAREL_STARTS = ("clip", "window")


def apparel_start(config: dict) -> str:
    """The config's ``apparel_start`` (``"window"`` in a config without the key)."""
    return config_choice(config, "apparel_start", APPAREL_STARTS, "window")


def rollout_span(frames: int, burn_in: int, window: int) -> tuple[list[int], int]:
    """From-rest rollouts of a clip of ``frames`` frames (``apparel_start="clip"``): their first frames
    and their length L = min(frames, burn_in + window). A request of the apparel protocol starts at the
    clip's first frame (where the simulation started from rest) or ``burn_in`` frames before its
    window, so a clip up to L frames long is one rollout from frame 0, a longer one any of
    frames 0..frames-L."""
    length = min(frames, burn_in + window)
    return list(range(frames - length + 1)), length


def scored_frames(start: int, length: int, window: int) -> np.ndarray:
    """(L,) bool frames of a from-rest rollout that the apparel protocol scores in some request that
    starts where it does: every frame of one started at the clip's first frame; the last ``window``
    of one started later (a request starts later than frame 0 only a full burn-in before its window)."""
    out = np.ones(length, bool)
    if start > 0:
        out[: length - window] = False
    return out


def _apparel_character(c: Prepared, context: StageContext, config: dict, r: np.random.Generator):
    """f_c's mask of ``c``, the drawn apparel vertices (A,), their EdgeConv neighbours (A, k), their
    mesh edges as neighbour pairs and the weights (N, Kb) their body states are skinned with; None
    when f_c finds no apparel."""
    mask = _predicted_mask(c, context, config)
    if not mask.any():
        return None
    idx = _pick_components(c, mask, config["apparel_points"], r)
    # whole components were drawn, so the drawn vertices' components are theirs in the whole mask
    labels = _mask_components(c, mask)[np.searchsorted(np.flatnonzero(mask), idx)]
    nb = component_neighbours(c.rest[idx], labels, config["knn"])
    w = mesh_weights(context.frozen["body"], c, mask, config.get("apparel_skinning", "fs"),
                     config.get("weight_smoothing", 0), config.get("weight_smoothing_radius", 0.0)).cpu()
    edges = np.stack([np.repeat(np.arange(len(idx)), nb.shape[1] - 1), nb[:, 1:].reshape(-1)], 1)
    return idx, nb, w, edges


def _apparel_body(c: Prepared, idx: np.ndarray, w: torch.Tensor, kin: np.ndarray) -> np.ndarray:
    """(F, A, 3) unit-height body states of the apparel vertices ``idx`` for transforms (F, K, 7)."""
    return to_unit(c, skin(torch.as_tensor(c.rest[idx]), torch.as_tensor(c.keypoints[c.body]), w[idx],
                           torch.as_tensor(kin[:, c.body]))).numpy()


def batches_apparel(config: dict, context: StageContext, rng: np.random.Generator):
    """One rollout a step (apparel vertex counts differ between characters). ``apparel_start="clip"``:
    a from-rest rollout (:func:`rollout_span`) with the frames a request would score
    (:func:`scored_frames`); ``"window"``: a window of ``window`` frames after K ground-truth states, a
    share ``rest_start`` of them restarted at rest on the body at the window."""
    if apparel_model(config) == "body_history" or apparel_start(config) == "clip":
        yield from _batches_apparel_clip(config, context, rng)
        return
    data = training_data(config, context)
    t = config["window"]
    windows = _windows(data, HISTORY, t)
    if not windows:
        raise ValueError(f"no clip has the {HISTORY + t} frames an apparel window needs (window={t})")
    for batch in _draws(config, context, rng, len(windows), "apparel"):
        for pick, seed in batch:
            ci, t0 = windows[pick]
            clip = data.clips[ci]
            c = data.characters[clip.character_id]
            r = np.random.default_rng(seed)
            found = _apparel_character(c, context, config, r)
            if found is None:
                continue
            idx, nb, w, edges = found
            frames = slice(t0 - HISTORY, t0 + t)
            kin = clip.kinematic[frames]
            s = _apparel_body(c, idx, w, kin)  # frames t0-3..t0+T-1
            truth = c.norm(posed(c, clip.simulated[frames], idx))
            history, body, joints = truth[:HISTORY], s[HISTORY - 1:], c.norm(kin[:, c.body, 4:])
            if r.random() < config["rest_start"]:  # at rest on the body at the window, not moving
                history = np.repeat(s[HISTORY:HISTORY + 1], HISTORY, 0)
                body = np.concatenate([s[HISTORY:HISTORY + 1], s[HISTORY:]])
                joints = np.concatenate([np.repeat(joints[HISTORY:HISTORY + 1], HISTORY, 0), joints[HISTORY:]])
            yield {"history": history[None], "body": body[None], "rest": c.rest_norm[idx][None],
                   "joints": joints[None], "neighbours": nb, "truth": truth[None, HISTORY:], "edges": edges}


def _batches_apparel_clip(config: dict, context: StageContext, rng: np.random.Generator):
    data = training_data(config, context)
    window = config["scored_window"]
    spans = [(i, t0, length) for i, clip in enumerate(data.clips)
             for starts, length in [rollout_span(clip.frames, config["burn_in"], window)] for t0 in starts]
    for batch in _draws(config, context, rng, len(spans), "apparel"):
        for pick, seed in batch:
            ci, t0, length = spans[pick]
            clip = data.clips[ci]
            c = data.characters[clip.character_id]
            found = _apparel_character(c, context, config, np.random.default_rng(seed))
            if found is None:
                continue
            idx, nb, w, edges = found
            kin = clip.kinematic[t0:t0 + length]
            item = {"body": _apparel_body(c, idx, w, kin)[None], "joints": c.norm(kin[:, c.body, 4:])[None],
                    "rest": c.rest_norm[idx][None], "neighbours": nb, "edges": edges,
                    "truth": c.norm(posed(c, clip.simulated[t0:t0 + length], idx))[None],
                    "scored": scored_frames(t0, length, window)}
            if apparel_model(config) == "body_history":
                rot, rest_offset = history_inputs(c, idx, w, kin)
                item["rotations"], item["rest_offset"] = rot[None].numpy(), rest_offset[None].numpy()
                item["mesh_edges"] = edges_among(c.edges, idx)
                item["scored"] = _some_frames(item["scored"], config.get("history_frames", 0),
                                              np.random.default_rng(seed))
            yield item


def _some_frames(scored: np.ndarray, n: int, r: np.random.Generator) -> np.ndarray:
    """(L,) bool: ``n`` of the ``scored`` frames drawn at random (0 or more than there are: all of them).
    The body-history model predicts every frame on its own, so a few frames a clip stand in for all."""
    on = np.flatnonzero(scored)
    if n <= 0 or n >= len(on):
        return scored
    out = np.zeros_like(scored)
    out[r.choice(on, size=n, replace=False)] = True
    return out


def apparel_states(module, batch, config: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """f_d's states and displacements (B, T, A, 3) for an apparel batch: from rest at its first frame
    through :func:`mimicbench.baselines.mmdmc.pipeline.rollout_from_rest` (inference's own path) when the batch
    has no ``history``, else from the batch's K history states. The body-history model gives every
    frame (its displacements are the offsets from the body states)."""
    if isinstance(module, BodyHistoryApparel):
        return module.states(batch["body"], batch["rotations"], batch["rest_offset"], None, batch["neighbours"])
    if "history" in batch:
        return module.rollout(batch["history"], batch["body"], batch["rest"], batch["joints"], batch["neighbours"])
    return rollout_from_rest(module, batch["body"], batch["rest"], batch["joints"], batch["neighbours"],
                             int(config.get("bptt", 0)))


def loss_apparel(module, batch, context) -> dict:
    truth = batch["truth"]
    if isinstance(module, BodyHistoryApparel):  # only the drawn scored frames are predicted
        on = torch.as_tensor(batch["scored"], dtype=torch.bool)
        states, disp = module.states(batch["body"], batch["rotations"], batch["rest_offset"], on, batch["neighbours"])
        truth = truth[:, on]
        return weighted_total({"vertex": vertex_l1(states, truth),
                               "stretch": edge_stretch(states, truth, batch["mesh_edges"]),
                               "reg": l2_regulariser(disp)}, context.config)
    states, disp = apparel_states(module, batch, context.config)
    if "scored" in batch:  # only the frames a request scores
        on = torch.as_tensor(batch["scored"], dtype=torch.bool)
        states, disp, truth = states[:, on], disp[:, on], truth[:, on]
    return weighted_total({"vertex": vertex_l1(states, truth),
                           "edge": edge_length(states, truth, batch["edges"]),
                           "reg": l2_regulariser(disp)}, context.config)


STAGES = [
    TrainStage("seg", build_seg, batches_seg, loss_seg),
    TrainStage("body", build_body, batches_body, loss_body),
    TrainStage("apparel", build_apparel, batches_apparel, loss_apparel, needs=("seg", "body")),
]
BUILDERS = {s.name: s.build for s in STAGES}

TRAINABLE = make_trainable("mmdmc", STAGES, CONFIGS)
