"""Config presets of the MimiCAT reference: ``small`` (2 CPU cores, minutes) and ``paper``.

One dict for all four stages; the trainer (:mod:`mimicbench.training.loop`) reads ``lr``,
``weight_decay``, ``grad_clip`` and ``epochs`` from a stage's section or the top level, and each
stage reads its own section. ``paper`` has the paper's transformer sizes (6 layers, 8 heads,
width 256, MLP 2048) and AdamW at lr 1e-4 (Sec. 4); ``small`` keeps every stage's structure at
sizes that train on 2 CPU cores in minutes, with a higher learning rate (5e-4) so that a few
epochs get somewhere. ``--set shape.width=128`` overrides a value.

Sections:
- ``data``: ``split`` the characters trained on (``train``, ``val``, ``test`` or ``all``);
  ``points`` P, the vertices E reads per mesh (rest or posed, in the rest frame: centre of the
  rest bounding box, divided by its largest side); ``frames_per_motion`` posed frames drawn per
  clip per epoch.
- ``shape`` (E, the shape autoencoder): ``tokens`` l_E, ``width`` d, ``heads``, ``layers``
  (self-attention blocks after the cross-attention), ``mlp``, ``decoder_layers``; ``queries``
  UDF query points per shape, ``surface_samples`` for the UDF target, ``fourier`` frequencies.
- ``prior`` (F): ``width``, ``heads``, ``layers``, ``mlp``, ``fourier``, ``output_scale``;
  ``sampling_weight`` and ``samples`` of the sampling term (A3; 0 turns it off);
  ``max_keypoints`` scored per character (more are subsampled each step).
- ``corr`` (G) and ``transfer`` (H): sizes and loss weights (see
  :mod:`mimicbench.baselines.mimicat.transfer_training`); ``corr.geometry_weight`` w0 of G's optional
  geometric affinity term on unit-height rest keypoints (0: off; see
  :mod:`mimicbench.baselines.mimicat.correspondence`); ``transfer_no_prior`` (H without L_reg, ablation
  A2) takes every setting from ``transfer`` except ``epochs``, which the loop reads per stage.
  Two values are our choices, measured on the training zoo (seed 11), not the paper's:
  ``transfer.m_temperature`` 0.1, the Sinkhorn temperature of the M that H's initialisation
  uses (G trains at 1; a flat M averages the pose away, see
  :func:`mimicbench.baselines.mimicat.transfer.correspondences`), and ``transfer.reg_weight`` 0.001: at
  0.01 the gradient of the weighted L_reg on H's parameters was 0.6 times that of L_rec at the
  start (norms 0.42 and 0.70), so H followed the prior rather than the cycle; at 0.001 it is a
  tenth, a regulariser. ``transfer.init`` is the construction of H's initialisation:
  ``structured`` (root displacement of the source root, carried local bone translations, empty
  columns inheriting the parent's rotation) or ``paper`` (Eq. 3-4 as published; what a config
  without the key means), see
  :mod:`mimicbench.baselines.mimicat.initialisation`. ``transfer.m_decode`` is how that initialisation
  reads G's M: ``hungarian_sym`` (the presets: one one-to-one decoding of the pair from G's M of
  both directions, so that a cycle's return leg undoes the forward leg's matches),
  ``hungarian`` (the one-to-one decoding of G(s, t) alone;
  G's Sinkhorn has no dustbin and its soft M blurs the carried translations and rotations, see
  :func:`mimicbench.baselines.mimicat.transfer.decode_correspondence`) or ``soft`` (M as it is; what a
  config without the key means).

The shipped checkpoints (``baselines/mimicat/checkpoints``) hold :func:`shipped_config` of their
stage: ``small`` with the training-budget overrides of :data:`SHIPPED_OVERRIDES`, so every setting
the method reads is ``small``'s; ``tests/test_mimicat_shipped_config.py`` checks each header.
"""
from __future__ import annotations

import copy

SMALL = {
    "lr": 5e-4,
    "weight_decay": 0.01,
    "grad_clip": 1.0,
    "data": {"split": "train", "points": 512, "frames_per_motion": 4},
    "shape": {"tokens": 16, "width": 64, "heads": 4, "layers": 2, "mlp": 128, "decoder_layers": 1,
              "fourier": 6, "queries": 512, "surface_samples": 4096, "batch_size": 8, "epochs": 12},
    "prior": {"width": 64, "heads": 4, "layers": 2, "mlp": 128, "fourier": 6,
              "max_keypoints": 64, "sampling_weight": 0.1, "samples": 4,
              "batch_size": 8, "epochs": 12},
    "corr": {"width": 64, "heads": 4, "layers": 2, "mlp": 128, "batch_size": 8, "epochs": 10, "sinkhorn_iters": 50,
             "geometry_weight": 0.0},
    "transfer": {"width": 64, "heads": 4, "layers": 2, "mlp": 128, "batch_size": 4, "epochs": 10,
                 "examples_per_epoch": 128, "same_skeleton_share": 0.3, "rec_weight": 1.0, "reg_weight": 0.001,
                 "feat_weight": 0.1, "m_temperature": 0.1, "init": "structured",
                 "m_decode": "hungarian_sym"},
    "transfer_no_prior": {"epochs": 10},
}

PAPER = {
    "lr": 1e-4,
    "weight_decay": 0.01,
    "grad_clip": 1.0,
    "data": {"split": "train", "points": 2048, "frames_per_motion": 16},
    "shape": {"tokens": 64, "width": 256, "heads": 8, "layers": 6, "mlp": 2048, "decoder_layers": 2,
              "fourier": 8, "queries": 2048, "surface_samples": 16384, "batch_size": 32, "epochs": 200},
    "prior": {"width": 256, "heads": 8, "layers": 6, "mlp": 2048, "fourier": 8,
              "max_keypoints": 256, "sampling_weight": 0.1, "samples": 8,
              "batch_size": 32, "epochs": 100},
    "corr": {"width": 256, "heads": 8, "layers": 6, "mlp": 2048, "batch_size": 32, "epochs": 100, "sinkhorn_iters": 50,
             "geometry_weight": 0.0},
    "transfer": {"width": 256, "heads": 8, "layers": 6, "mlp": 2048, "batch_size": 16, "epochs": 100,
                 "examples_per_epoch": 4096, "same_skeleton_share": 0.3, "rec_weight": 1.0, "reg_weight": 0.001,
                 "feat_weight": 0.1, "m_temperature": 0.1, "init": "structured",
                 "m_decode": "hungarian_sym"},
    "transfer_no_prior": {"epochs": 100},
}

PRESETS = {"small": SMALL, "paper": PAPER}

SHIPPED_STAGES = ("shape", "prior", "corr", "transfer", "transfer_no_prior")
"""The stages whose weights ship in ``baselines/mimicat/checkpoints/<stage>.safetensors``."""

SHIPPED_OVERRIDES = {
    "shape": {"data.split": "all", "shape.epochs": 10},
    "prior": {"data.split": "all", "prior.epochs": 8, "prior.sampling_weight": 0},
    "corr": {"data.split": "all"},
    "transfer": {"data.split": "all"},
    "transfer_no_prior": {"data.split": "all"},
}
"""Per shipped stage, the ``--set`` overrides of ``small`` it was trained with: the training budget
and data only (every character of the training zoo, fewer epochs, the prior's sampling term off for
time), never a setting the method reads at inference (sizes, ``m_temperature``, ``init``,
``m_decode``, ``geometry_weight``); :data:`BUDGET_KEYS` lists what an override may touch."""

SHIPPED_RANGE = {"k": 3, "slack_deg": 0.0, "parts": "both", "keep": "local", "scope": "free", "max_deg": 180.0,
                 "feature_scales": {"axis": 2.0, "position": 1.0, "parent_axis": 1.0, "length": 4.0, "children": 0.5,
                                    "depth": 0.5}}
"""Settings of the shipped range model (``checkpoints/range.safetensors``, see
:mod:`mimicbench.baselines.mimicat.range_model`), chosen on the training zoo (seed 11) with each
target's own bones left out of the neighbours: ``scope=free`` (only the bones G matches to no
source bone move; they share the turn between their matched neighbours and are moved into the
range of their 3 nearest training bones); ``tests/test_mimicat_shipped_config.py`` checks the file."""

BUDGET_KEYS = ("data.split", "shape.epochs", "prior.epochs", "prior.sampling_weight", "corr.epochs",
               "transfer.epochs", "transfer_no_prior.epochs")
"""Settings that change how a stage is trained but not what the trained module computes."""

STAGE_SECTIONS = {"shape": ("data", "shape"), "prior": ("data", "shape", "prior"),
                  "corr": ("data", "shape", "corr"), "transfer": ("data", "shape", "corr", "transfer"),
                  "transfer_no_prior": ("data", "shape", "corr", "transfer", "transfer_no_prior")}
"""Config sections each stage reads (its own, the data, E's width; H also reads ``corr`` for G's M
and A2 takes every setting of ``transfer``), besides the loop's top-level ``lr``, ``weight_decay``
and ``grad_clip``."""


def preset(name: str) -> dict:
    """A deep copy of the preset ``name`` (``small`` or ``paper``)."""
    if name not in PRESETS:
        raise ValueError(f"unknown MimiCAT config {name!r}; expected one of {', '.join(PRESETS)}")
    return copy.deepcopy(PRESETS[name])


def shipped_config(stage: str) -> dict:
    """The documented config of the shipped checkpoint of ``stage``: ``small`` with
    :data:`SHIPPED_OVERRIDES` applied (each dotted key ``section.key`` or a top-level key)."""
    if stage not in SHIPPED_OVERRIDES:
        raise ValueError(f"unknown shipped MimiCAT stage {stage!r}; expected one of {', '.join(SHIPPED_STAGES)}")
    config = preset("small")
    for key, value in SHIPPED_OVERRIDES[stage].items():
        section, _, name = key.rpartition(".")
        (config.setdefault(section, {}) if section else config)[name] = value
    return config
