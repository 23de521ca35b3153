"""The pose-transfer transformer H (MimiCAT Eq. 3, 4, 7, 8).

For a source pose and a target character, with a soft correspondence M from G:

1. Initialisation (:mod:`mimicbench.baselines.mimicat.initialisation`; ``init="structured"``, the presets'
   default, or ``"paper"``, Eq. 3-4 as published): per target keypoint j a rotation q̄_j and a
   position t̄_j.
2. Shape conditioning: the residual feature ``delta_f = E(V_s posed) - E(V_s rest)`` (l_E, d)
   says how the source's shape moved; the target's rest shape tokens E(V_t) attend to it
   (cross-attention, queries from the target, keys and values from delta_f), giving posed
   target shape tokens.
3. Keypoint tokens from ``[c_j, c̄_j, t̄_j, q̄_j]``: the target's skeleton features (rest
   position c_j among them), the M-weighted source rest keypoint c̄_j (source frame), the
   initial displacement (t̄_j - c_j) / size and q̄_j.
4. Transformer blocks over keypoint and shape tokens (padding masked), a decoder to a
   per-keypoint correction (δ rotation, δ translation): ``q_j = q̄_j ⊗ normalise(1, δ)``,
   ``t_j = t̄_j + size · δt``. The decoder's last layer starts at zero, so an untrained H returns
   the initialisation exactly and training can only move away from it where the losses say so.
5. LBS (Eq. 1) poses the target mesh.

Training (Eq. 7-8) is by cycle consistency, see :mod:`mimicbench.baselines.mimicat.transfer_losses`.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.baselines.mimicat.correspondence import mlp, transformer
from mimicbench.baselines.mimicat.corr_data import KEYPOINT_FEATURES
from mimicbench.baselines.mimicat.initialisation import initialise
from mimicbench.baselines.mimicat.transfer_data import CharacterTensors, pad
from mimicbench.geometry.skinning_torch import linear_blend_skinning_torch

TOKEN_FEATURES = KEYPOINT_FEATURES + 3 + 3 + 4


def quat_multiply_torch(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product (..., 4) of quaternions (w, x, y, z)."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], dim=-1)


def pose_mesh(char: CharacterTensors, q: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """The character's vertices (N, 3) posed by global rotations q (K, 4) and positions t (K, 3) (LBS)."""
    transforms = torch.cat([q, t], dim=-1).to(torch.float32)
    return linear_blend_skinning_torch(char.vertices, char.keypoints, char.weight_values, transforms,
                                       char.weight_indices)


class PoseTransferTransformer(nn.Module):
    """H: source pose + target character + M -> target transforms (q, t) per keypoint.

    Args:
        shape_width: width d of the shape encoder's tokens.
        width, layers, heads, mlp_width: transformer sizes.
        average: rotation average of the initialisation, ``eq4`` or ``naive`` (ablation A1).
        init: construction of the initialisation, ``structured`` or ``paper``
            (:func:`mimicbench.baselines.mimicat.initialisation.initialise`).
    """

    def __init__(self, shape_width: int, width: int = 64, layers: int = 2, heads: int = 4, mlp_width: int = 128,
                 average: str = "eq4", init: str = "structured"):
        super().__init__()
        from mimicbench.baselines.mimicat.initialisation import INITS

        if init not in INITS:
            raise ValueError(f"init: expected one of {INITS}, got {init!r}")
        self.average = average
        self.init = init
        self.token_encoder = mlp(TOKEN_FEATURES, width, width)
        self.target_projector = nn.Linear(shape_width, width)
        self.delta_projector = nn.Linear(shape_width, width)
        self.cross = nn.MultiheadAttention(width, heads, batch_first=True)
        self.cross_norm = nn.LayerNorm(width)
        self.segment = nn.Embedding(2, width)  # keypoint token, shape token
        self.blocks = transformer(width, layers, heads, mlp_width)
        self.norm = nn.LayerNorm(width)
        self.decoder = mlp(width, width, 6)
        nn.init.zeros_(self.decoder[-1].weight)
        nn.init.zeros_(self.decoder[-1].bias)

    def initialise(self, src: CharacterTensors, q_src: torch.Tensor, t_src: torch.Tensor, tgt: CharacterTensors,
                   m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The initialisation for one pair: q̄ (Kt, 4), t̄ (Kt, 3) and the keypoint token inputs (Kt, TOKEN_FEATURES)."""
        q_bar, t_bar = initialise(self.init, q_src, t_src, src.keypoints, src.parents, tgt.keypoints, tgt.parents, m,
                                  tgt.size / src.size, self.average)
        q_bar, t_bar = q_bar.to(torch.float32), t_bar.to(torch.float32)
        mf = m.to(torch.float32)
        mass = mf.sum(dim=0, keepdim=True).clamp_min(1e-9)
        c_bar = (mf / mass).T @ ((src.keypoints - src.centre) / src.size)
        tokens = torch.cat([tgt.features, c_bar, (t_bar - tgt.keypoints) / tgt.size, q_bar], dim=-1)
        return q_bar, t_bar, tokens

    def forward(self, src: list[CharacterTensors], q_src: list[torch.Tensor], t_src: list[torch.Tensor],
                tgt: list[CharacterTensors], m: list[torch.Tensor], delta_f: torch.Tensor,
                shape_t: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """Per pair of the batch, the target's global rotations (Kt, 4) and positions (Kt, 3).

        Args:
            src, tgt: the B source and target characters.
            q_src, t_src: per pair (Ks, 4) source global rotations and (Ks, 3) posed keypoints.
            m: per pair (Ks, Kt) soft correspondence.
            delta_f: (B, l, d) E(source posed) - E(source rest).
            shape_t: (B, l, d) E(target rest).
        """
        inits = [self.initialise(s, q, t, g, mm) for s, q, t, g, mm in zip(src, q_src, t_src, tgt, m)]
        tokens, mask = pad([i[2] for i in inits])
        kp = self.token_encoder(tokens) + self.segment.weight[0]
        query = self.target_projector(shape_t)
        delta = self.delta_projector(delta_f)
        posed_shape = self.cross_norm(query + self.cross(query, delta, delta, need_weights=False)[0])
        h = torch.cat([kp, posed_shape + self.segment.weight[1]], dim=1)
        valid = torch.cat([mask, torch.ones(mask.shape[0], posed_shape.shape[1], dtype=torch.bool,
                                            device=mask.device)], dim=1)
        h = self.norm(self.blocks(h, src_key_padding_mask=~valid))
        out = self.decoder(h[:, :kp.shape[1]])
        result = []
        for b, (q_bar, t_bar, _) in enumerate(inits):
            k = len(q_bar)
            dq = torch.cat([torch.ones_like(out[b, :k, :1]), out[b, :k, :3]], dim=-1)
            dq = dq / dq.norm(dim=-1, keepdim=True)
            result.append((quat_multiply_torch(q_bar, dq), t_bar + tgt[b].size * out[b, :k, 3:]))
        return result


def encode_pair_shapes(encoder: nn.Module, src: list[CharacterTensors], src_posed: list[torch.Tensor],
                       tgt: list[CharacterTensors], rest_cache: dict | None = None
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """E's tokens for a batch: source rest, source posed, target rest (each (B, l, d)) and delta_f.

    ``rest_cache``: character ID -> (l, d) rest tokens of a frozen E, filled and read here, so that
    E reads each rest mesh once (None: every rest mesh through E again with the posed ones).
    """
    from mimicbench.baselines.mimicat.transfer_data import shape_tokens

    b = len(src)
    if rest_cache is None:
        pts = torch.stack([s.normalised(s.vertices) for s in src] + [s.normalised(p) for s, p in zip(src, src_posed)]
                          + [t.normalised(t.vertices) for t in tgt])
        tok = shape_tokens(encoder, pts)
        f_s, f_sp, f_t = tok[:b], tok[b:2 * b], tok[2 * b:]
        return f_s, f_sp, f_t, f_sp - f_s
    missing = list({c.character_id: c for c in src + tgt if c.character_id not in rest_cache}.values())
    if missing:
        with torch.no_grad():
            tok = shape_tokens(encoder, torch.stack([c.normalised(c.vertices) for c in missing]))
        rest_cache.update({c.character_id: t for c, t in zip(missing, tok)})
    f_sp = shape_tokens(encoder, torch.stack([s.normalised(p) for s, p in zip(src, src_posed)]))
    f_s = torch.stack([rest_cache[s.character_id] for s in src])
    f_t = torch.stack([rest_cache[t.character_id] for t in tgt])
    return f_s, f_sp, f_t, f_sp - f_s


def transfer_batch(encoder: nn.Module, g: nn.Module, h: PoseTransferTransformer, src: list[CharacterTensors],
                   q_src: list[torch.Tensor], t_src: list[torch.Tensor], src_posed: list[torch.Tensor],
                   tgt: list[CharacterTensors], m: list[torch.Tensor] | None = None, rest_cache: dict | None = None):
    """The cascade E -> G -> H for a batch of pairs.

    Args:
        encoder: the shape encoder E; g: the correspondence transformer G (used when ``m`` is None);
            h: the pose-transfer transformer H.
        src, tgt: characters; q_src, t_src: per pair the source pose (Ks, 4), (Ks, 3);
        src_posed: per pair the posed source vertices (Ns, 3).
        m: per pair (Ks, Kt) correspondences to use instead of G's.
        rest_cache: rest tokens of a frozen E by character ID (see :func:`encode_pair_shapes`).

    Returns:
        ``[(q (Kt, 4), t (Kt, 3))]``, the correspondences used, and the shape tokens
        ``(f_s, f_sp, f_t, delta_f)``.
    """
    f_s, f_sp, f_t, delta_f = encode_pair_shapes(encoder, src, src_posed, tgt, rest_cache)
    if m is None:
        from mimicbench.baselines.mimicat.transfer_data import correspondence_inputs

        m = g(shape_s=f_s, shape_t=f_t, **correspondence_inputs(src, tgt))
    return h(src, q_src, t_src, tgt, m, delta_f, f_t), m, (f_s, f_sp, f_t, delta_f)


def correspondences(encoder: nn.Module, g: nn.Module, src: list[CharacterTensors], tgt: list[CharacterTensors],
                    cache: dict | None = None, temperature: float = 1.0) -> list[torch.Tensor]:
    """G's soft correspondences (Ks, Kt) for pairs of rest characters, from ``cache`` (keyed by
    the two character IDs and ``temperature``) when there; G is frozen once trained, so M depends
    on the pair alone.

    ``temperature`` T is the Sinkhorn temperature of the M that H's initialisation uses (config
    ``transfer.m_temperature``). G is trained at T = 1 against the dataset's M_sink, whose rows
    are flat across categories (mean row maximum of G's M 0.32 on the training zoo), and Eq. 4
    with a flat M averages many source rotations into one and loses the pose. A sharper M from
    the same scores keeps it: on 48 cycles of the training zoo (untrained H, shipped G of the
    previous release) the cycle error was 0.0236 of the source's size at T = 1, 0.0206 at 0.3,
    0.0203 at 0.1 and 0.0202 at 0.03; a one-to-one Hungarian decoding of M gave 0.0209 (all with
    the ``paper`` initialisation). M stays doubly stochastic (and soft where G's scores are
    close), so Eq. 4 still averages. The structured initialisation reads it one to one instead
    (:func:`decode_correspondence`, config ``transfer.m_decode``).
    """
    cache = {} if cache is None else cache
    keys = [(s.character_id, t.character_id, float(temperature)) for s, t in zip(src, tgt)]
    todo = [i for i, k in enumerate(keys) if k not in cache]
    if todo:
        from mimicbench.baselines.mimicat.transfer_data import correspondence_inputs, shape_tokens

        with torch.no_grad():
            tok = shape_tokens(encoder, torch.stack([src[i].normalised(src[i].vertices) for i in todo]
                                                    + [tgt[i].normalised(tgt[i].vertices) for i in todo]))
            ms = g(shape_s=tok[:len(todo)], shape_t=tok[len(todo):], temperature=temperature,
                   **correspondence_inputs([src[i] for i in todo], [tgt[i] for i in todo]))
        for i, m in zip(todo, ms):
            cache[keys[i]] = m.detach()
    return [cache[k] for k in keys]


DECODES = ("soft", "hungarian", "hungarian_sym")
NEEDS_REVERSE = ("hungarian_sym",)
"""Decodings that read G's correspondence of the reversed pair too."""


def decode_correspondence(m: torch.Tensor, decode: str = "soft", m_reverse: torch.Tensor | None = None,
                          allowed: np.ndarray | None = None) -> torch.Tensor:
    """The M (Ks, Kt) that H's initialisation reads from G's soft correspondence m (Ks, Kt)
    (config ``transfer.m_decode``).

    ``soft``: m itself. ``hungarian``: the one-to-one decoding of m, a 0/1 matrix with a 1 at
    each pair of the assignment maximising the summed entries
    (:func:`mimicbench.geometry.hungarian.hungarian_match`; min(Ks, Kt) pairs, so the larger side keeps
    unmatched bones, whose empty columns the structured initialisation fills from the parent).
    G's Sinkhorn has no dustbin: every target column of m carries mass, spread over several
    source bones where G hesitates, and the structured initialisation's carried translations
    and Eq. 4's average then blur the pose; the one-to-one decoding keeps each bone's single
    best match (it is ``nearest_joint``'s construction from G's matches). G is frozen when H
    trains, so the decoding is a constant for H (no gradient flows into m either way).

    ``hungarian_sym``: the one-to-one decoding of ``m + m_reverse.T``, ``m_reverse`` (Kt, Ks)
    being G's correspondence of the reversed pair (target to source), so the pair's decoding
    is one assignment whichever way round it is asked for (the reversed pair's is its
    transpose, ties aside). ``hungarian`` decodes G(s, t) and G(t, s) apart, and G is not
    symmetric: on a training zoo's cycles a third of the bones matched going out came back to
    another source bone, and those bones carried 42% of the initialisation's cycle error, an
    error of the pair, not of the pose, that H could only memorise pair by pair.

    ``allowed`` (Ks, Kt) bool, for the one-to-one decodings only: the pairs the assignment may use
    (:func:`determined_pairs`); the best assignment over them, a bone whose every allowed partner
    is taken left unmatched. None: every pair.
    """
    if decode not in DECODES:
        raise ValueError(f"transfer.m_decode: expected one of {DECODES}, got {decode!r}")
    if decode == "soft":
        return m
    from mimicbench.geometry.hungarian import hungarian_match

    if decode == "hungarian_sym":
        if m_reverse is None or tuple(m_reverse.shape) != tuple(m.shape[::-1]):
            raise ValueError(f"transfer.m_decode=hungarian_sym: expected the reversed pair's M of shape "
                             f"{tuple(m.shape[::-1])}, got {None if m_reverse is None else tuple(m_reverse.shape)}")
        scores = (m + m_reverse.T.to(m.dtype)).detach().cpu().numpy()
    else:
        scores = m.detach().cpu().numpy()
    if allowed is not None:
        allowed = np.asarray(allowed, bool)
        if allowed.shape != scores.shape:
            raise ValueError(f"allowed: expected shape {scores.shape}, got {allowed.shape}")
        scores = np.where(allowed, scores, scores.min() - 1.0 - np.abs(scores).max() * scores.size)
    _, onehot = hungarian_match(scores, maximize=True)
    if allowed is not None:
        onehot = onehot * allowed
    return torch.as_tensor(onehot, dtype=m.dtype, device=m.device)


def determined_pairs(determined_src: np.ndarray, determined_tgt: np.ndarray) -> np.ndarray:
    """(Ks, Kt) bool: the pairs whose bones the mesh either determines on both sides or on
    neither (:func:`mimicbench.geometry.transform_estimation.weight_support`). A bone without
    skin weight (an artist rig's IK target, twist helper or control bone) has no pose on the
    posed mesh, only one completed from its neighbours, and moves no vertex: matched to a bone
    that owns vertices it hands that bone a rotation the source's mesh never showed, and the
    return leg cannot read it back. The rule is symmetric, so the reversed pair allows the
    transposed pairs and ``hungarian_sym`` stays one assignment of the pair."""
    s, t = np.asarray(determined_src, bool), np.asarray(determined_tgt, bool)
    return s[:, None] == t[None, :]


def as_numpy_transforms(q: torch.Tensor, t: torch.Tensor) -> np.ndarray:
    """(K, 7) float32 transforms from torch rotations and positions."""
    return torch.cat([q, t], dim=-1).detach().cpu().numpy().astype(np.float32)
