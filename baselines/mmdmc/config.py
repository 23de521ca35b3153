"""Config presets of the MMDMC reference: ``small`` (trains on 2 CPU cores in minutes; the shipped
checkpoint) and ``paper`` (the paper's sizes and AdamW lr 1e-4, for GPUs).

Every key is flat so ``mimicbench train mmdmc ... --set key=value`` can override it.
Loss weights are the paper's: vertex 1.0, edge 100, weight smoothness and regulariser 0.01.
``small`` raises the learning rate to 1e-3 because it trains for minutes, not days.
"""
from __future__ import annotations

COMMON = {
    "history": 3,            # K: apparel states a step looks back on (Eq. 11); fixed by the model's inputs
    "window": 10,            # T: frames an apparel training window rolls out (Eq. 11)
    "w_vertex": 1.0,
    "w_edge": 100.0,
    "w_smooth": 0.01,
    "w_reg": 0.01,
    "w_weights": 1.0,        # ours, not the paper's: L1 of f_s's weights against the body target's (see training.py)
    "weights_on": "all",     # ours: vertices that L1 term averages over, "all" (the shipped model's) or "body"
    "seg_body_clips": "simulated",  # clips seg and body read: "simulated" (pairs with '<clip>@sim', the shipped
                                    # model's) or "kinematic" (every clip; a zoo never simulated will do)
    "seg_inputs": "positions",     # ours: f_c's inputs, "positions" (the paper's, the first shipped model's) or
                                   # "bones" (plus distances to the nearest body and apparel bone; segmentation.py)
    "apparel_skinning": "fs",      # ours: how the vertices of f_c's mask are skinned before f_d displaces them,
                                   # "fs" (f_s's weights) or "attachment" (the body bone their chain hangs from;
                                   # chain_attachment.py)
    "weight_smoothing": 0,         # ours: iterations f_s's weights are smoothed along the mesh (weight_smoothing.py)
    "weight_smoothing_radius": 0.0,  # ours: then diffused over this share of the height (weight_smoothing.py)
    "mask_by_piece": False,        # ours: f_c's probability averaged over each mesh piece (pipeline.py)
    "bridge_neighbours": 4,  # geodesic graph: nearest vertices looked at for bridges between mesh pieces
    "knn": 8,                # EdgeConv neighbours, within one connected apparel component
    "neighbours_loss": 6,    # rest-pose neighbours standing in for mesh edges on a vertex subsample
    "body_edge_loss": "knn",  # ours: f_s's edge term (Eq. 9), "knn" (squared length difference on those
                              # neighbour pairs, models up to v5) or "mesh_stretch" (|l_pred/l_truth - 1| on real
                              # mesh edges: the subsample is drawn as the ends of random mesh edges; training.py)
    "body_prior": "bone",    # ours: f_s's prior on its scores, "bone" (-B / tau, models up to v5) or "piece" (the
                             # piece prior alone where a mesh piece wraps a bone, at inference; piece_prior.py)
    "threshold": 0.5,        # apparel probability above which a vertex is apparel
    "apparel_start": "window",  # ours: f_d's training rollouts, "clip" (from rest on the body at the clip's first
                              # frame, as the simulation and a request start, through the burn-in; opt-in) or
                              # "window" (`window` frames after K ground-truth states, a share `rest_start` of them
                              # restarted at rest at the window, inside the clip; the default); training.py
    "burn_in": 90,           # "clip": most frames before a scored window (the apparel protocol's BURN_IN)
    "scored_window": 16,     # "clip": frames of a scored window (the apparel protocol's WINDOW)
    "bptt": 3,               # "clip": truncated backpropagation every that many rollout steps (0: none; full
                             # backpropagation through a from-rest rollout did not learn a toy lag, tests)
    "apparel_model": "rollout",  # ours: f_d, "rollout" (the paper's recurrence on K = 3 apparel states, apparel.py)
                                 # or "body_history" (a per-vertex MLP on the body's motion history in
                                 # the frame bone's frame, apparel_history.py; the shipped checkpoint's)
    "history_hidden": 256,   # "body_history": MLP width
    "history_layers": 3,     # "body_history": hidden layers
    "history_frames": 8,     # "body_history": scored frames a clip contributes to a step (0: all)
    "history_smoothing": 0,  # "body_history": passes averaging the offsets over each vertex's component neighbours
    "history_still_zero": False,  # "body_history": the offset is the MLP's less its answer for a still body
                             # (so a body that does not move keeps its skinned apparel; the shipped checkpoint: true)
    "history_arap": 0.0,     # "body_history": a request's apparel restored by soft ARAP with this pull towards
                             # f_d's prediction (apparel_arap.py; 0: not restored; the shipped checkpoint: 0.03)
    "w_stretch": 1.0,        # "body_history": weight of the apparel mesh edges' relative stretch (what ELS scores)
    "rest_start": 0.5,       # "window" only: share of the windows restarted at rest on the body at the window
}

SMALL = {**COMMON, "lr": 1e-3, "weight_decay": 1e-4, "points": 1024, "batch_size": 4, "batches_per_epoch": 40,
         "seg_hidden": 64, "body_hidden": 32, "apparel_hidden": 48, "code": 16,
         "apparel_points": 1024,
         # per-stage settings (the trainer reads config[stage][key] before config[key])
         "seg": {"epochs": 12}, "body": {"epochs": 6, "batches_per_epoch": 100, "points": 512},
         "apparel": {"epochs": 2, "batches_per_epoch": 12}}

PAPER = {**COMMON, "lr": 1e-4, "weight_decay": 1e-4, "points": 4096, "batch_size": 8, "batches_per_epoch": 500,
         "seg_hidden": 128, "body_hidden": 64, "apparel_hidden": 128, "code": 64,
         "apparel_points": 0,
         "seg": {"epochs": 20}, "body": {"epochs": 50}, "apparel": {"epochs": 30}}

CONFIGS = {"small": SMALL, "paper": PAPER}
