"""``apparel``: motion transfer on characters with simulated apparel (MMDMC's task).

Cases (cases version :data:`CASES_VERSION`): a character with apparel bones and a window of
``WINDOW`` consecutive frames of one of its clips that ``datagen apparel`` simulated (the motion
``<clip>@sim`` beside the kinematic ``<clip>``). The case row's ``source_id`` and ``target_id`` are
the character, ``motion_id`` the kinematic clip, ``frame`` the window's first frame;
``source_transforms`` holds the kinematic clip from the request's first frame to the window's end,
(B+F)*K rows, and ``target_transforms`` the simulated window, F*K rows (F frames of K bones, frame
after frame). B, the burn-in, is the frames before the window: the request starts where the
simulation started (the clip's first frame, where the apparel hangs at rest after the relaxation
frames) unless the window starts more than :data:`BURN_IN` frames in, then ``BURN_IN`` frames
before it; B = rows(source) / K - rows(target) / K. Rows with B = 0 (the kinematic window alone,
written before the burn-in existed; CHANGELOG.md) still evaluate.

Request (:class:`mimicbench.benchmark.request.MotionRequest`): the character at rest with its rig, the
kinematic frames (B+F, K, 7) with the mask of body bones, and the fps; the apparel vertex mask is
not given (except to oracle ablations tagged ``reads_gt_apparel_mask``, in ``extras``). The method
returns the posed mesh of every frame of the request, (B+F, N, 3); only the last F (the window)
are scored.

Ground truth: the simulated window posed by LBS. Scores per frame, then the mean over the
window (MMDMC): PMD over all vertices, PMD_a over the ground truth's apparel vertices and PMD_b
over the others, x100 of the target's height (``pmd``/``pmd_height``, ``pmd_apparel``,
``pmd_body``) and in centimetres of the character scaled to 1.70 m (``*_cm``), and ELS against the
ground truth's edge lengths; the per-frame values are kept in the ``*_frames`` columns.
Over the window as a whole (:mod:`mimicbench.benchmark.apparel_metrics`): ``accel_error``, the mean
``|a_pred - a_gt|`` over apparel vertices and the window's F - 2 second differences at the clip's
fps (m/s^2 at 1.70 m height), which sees apparel that shakes frame to frame where PMD_a barely
moves, and ``penetration_share``, the percent of apparel vertices within 1 mm (at 1.70 m) of the
ground truth's body pieces or inside them (HOOD), mean over the window's frames.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from mimicbench.benchmark.apparel_metrics import (accel_error, character_body_pieces, clear_at_rest, contact_reach,
                                       penetration_share)
from mimicbench.benchmark.metrics import els, pmd
from mimicbench.benchmark.normalisation import RestFrame
from mimicbench.benchmark.protocols.base import BenchmarkProtocol, Call, CaseDraw, CasePool, EvalData, Outcome
from mimicbench.benchmark.request import MotionRequest
from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.motion import SIM_SUFFIX

WINDOW = 16
"""Frames a case scores."""
BURN_IN = 90
"""Most frames of kinematic motion a request carries before its window (3 s at 30 fps). A window
that starts later than this in its clip gets a request that starts BURN_IN frames before it, where
the simulated apparel is no longer at rest: a method started there at rest carries what is left of
that lag (damped over BURN_IN frames) into the window. The cap bounds a request at BURN_IN + WINDOW
frames (106: about 6.6x the frames of a 16-frame request to compute)."""
CASES_VERSION = 2
"""Version of the apparel case rows: 2 adds the burn-in frames to ``source_transforms``."""
DEFAULT_FPS = 30.0
"""The fps a request states when the evaluation data does not know the clip's."""
REFERENCE_HEIGHT_CM = 170.0
"""MMDMC reports centimetres of a character 1.70 m tall."""
GT_MASK_TAG = "reads_gt_apparel_mask"
"""A method whose metadata.tags hold this (an oracle ablation such as ``mmdmc_gt_mask``) gets the
ground-truth apparel vertex mask in ``request.extras["apparel_vertex_mask"]``; no other method does."""


def apparel_scores(pred: np.ndarray, truth: np.ndarray, apparel: np.ndarray, frame: RestFrame) -> dict:
    """Per-frame and window-mean scores of predicted vs ground-truth meshes (F, N, 3).

    Args:
        apparel: (N,) bool ground-truth apparel vertices.
        frame: the target's rest frame (its height divides; its edges serve ELS).
    """
    apparel = np.asarray(apparel, bool)

    def per_frame(mask):
        if not mask.any():
            return None
        return [pmd(p[mask], t[mask], frame, "height") for p, t in zip(pred, truth)]

    frames = {"pmd_frames": per_frame(np.ones(len(apparel), bool)), "pmd_apparel_frames": per_frame(apparel),
              "pmd_body_frames": per_frame(~apparel),
              "els_frames": [els(p, t, frame.edges) for p, t in zip(pred, truth)]}
    mean = {k: (None if v is None else float(np.mean(v))) for k, v in frames.items()}
    out = {"pmd": mean["pmd_frames"], "pmd_height": mean["pmd_frames"], "pmd_apparel": mean["pmd_apparel_frames"],
           "pmd_body": mean["pmd_body_frames"], "els": mean["els_frames"], **frames}
    for key in ("pmd", "pmd_apparel", "pmd_body"):
        out[f"{key}_cm"] = None if out[key] is None else out[key] / 100.0 * REFERENCE_HEIGHT_CM
    return out


def burn_in_start(frame: int, cap: int = BURN_IN) -> int:
    """First clip frame of the request of a window that starts at ``frame``: the clip's first frame
    (where the simulation started from rest), or ``cap`` frames before the window."""
    return max(0, int(frame) - int(cap))


def burn_in_frames(case: CaseRecord, bones: int) -> int:
    """B: the frames of ``case``'s request before its window (``bones`` = K)."""
    total, window = len(case.source_transforms) // bones, len(case.target_transforms) // bones
    if total * bones != len(case.source_transforms) or window * bones != len(case.target_transforms) \
            or window < 1 or total < window:
        raise ValueError(f"{case.case_id}: apparel case rows must be (B+F)*K source and F*K target rows with "
                         f"K={bones}, F>=1, B>=0; got {len(case.source_transforms)} and {len(case.target_transforms)}")
    return total - window


class ApparelMotion(BenchmarkProtocol):
    name = "apparel"
    title = "apparel motion transfer: body motion in, the posed mesh with simulated apparel out"
    headline = "height"
    window = WINDOW

    def candidate_pairs(self, pool: CasePool) -> list[tuple]:
        return [(c, c) for c in pool.characters if np.asarray(c.apparel_bone_mask).any()
                and any(m.name.endswith(SIM_SUFFIX) for m in pool.motions.get(c.character_id, []))]

    def draw_cases(self, pool: CasePool, pairs: int | None, poses: int, seed: int = 0) -> list[CaseDraw]:
        """``poses`` windows per simulated clip of ``pairs`` characters (None: every one), drawn
        with the protocol's seeded generator."""
        rng = self.rng(seed)
        chars = [a for a, _ in self.candidate_pairs(pool)]
        if pairs is not None and len(chars) > pairs:
            chars = [chars[i] for i in sorted(rng.choice(len(chars), size=pairs, replace=False))]
        cases = []
        for c in chars:
            motions = {m.motion_id: m for m in pool.motions.get(c.character_id, [])}
            for sim in sorted((m for m in motions.values() if m.name.endswith(SIM_SUFFIX)), key=lambda m: m.motion_id):
                kin = motions.get(sim.motion_id[: -len(SIM_SUFFIX)])
                if kin is None or kin.num_frames != sim.num_frames:
                    continue
                window = min(self.window, kin.num_frames)
                starts = np.arange(kin.num_frames - window + 1)
                for start in sorted(rng.choice(starts, size=min(poses, len(starts)), replace=False)):
                    cases.append(CaseDraw(c, c, (kin, sim), int(start)))
        return cases

    def make_case(self, source, target, motion, frame: int) -> CaseRecord:
        """``motion`` is the pair (kinematic clip, simulated clip); ``frame`` the window's start.
        The kinematic rows start :func:`burn_in_start` frames in, the simulated ones at ``frame``."""
        kin, sim = motion
        window = min(self.window, kin.num_frames - frame)
        end = frame + window
        return CaseRecord(self.case_id(source, target, kin, frame), self.name, source.character_id,
                          target.character_id, kin.motion_id, frame,
                          kin.transforms[burn_in_start(frame):end].reshape(-1, 7),
                          sim.transforms[frame:end].reshape(-1, 7), source.category, target.category)

    def body_contact(self, char) -> tuple:
        """(body pieces, (A,) bool apparel vertices clear of the body at rest, reach in metres) of a
        character (:class:`~mimicbench.benchmark.rigs.CharacterData`), cached per character."""
        cache = self.__dict__.setdefault("_contact", {})
        cid = char.rig.character_id
        if cid not in cache:
            r = char.record
            apparel = np.asarray(r.apparel_vertex_mask, bool)
            vertices = np.asarray(r.vertices, np.float64)
            pieces = character_body_pieces(vertices, r.keypoints, r.weights, r.apparel_bone_mask)
            reach = contact_reach(float(np.ptp(vertices[:, 1])))
            cache[cid] = (pieces, clear_at_rest(pieces, r.keypoints, vertices[apparel], reach), reach)
        return cache[cid]

    def motion_scores(self, char, pred: np.ndarray, truth: np.ndarray, transforms: np.ndarray, fps: float,
                      height: float) -> dict:
        """``accel_error`` and ``penetration_share`` of a window: ``pred`` and ``truth`` (F, N, 3),
        ``transforms`` (F, K, 7) the ground truth's bones, ``height`` the target's rest height (m)."""
        apparel = np.asarray(char.record.apparel_vertex_mask, bool)
        if not apparel.any():
            return {"accel_error": None, "penetration_share": None}
        pieces, counted, reach = self.body_contact(char)
        return {"accel_error": accel_error(pred, truth, apparel, fps, height),
                "penetration_share": penetration_share(np.asarray(pred)[:, apparel], pieces, transforms, counted,
                                                       reach)}

    def evaluate(self, cases: Sequence[CaseRecord], data: EvalData, call: Call) -> list[Outcome]:
        chars = [data.characters[c.target_id] for c in cases]
        burn = [burn_in_frames(c, len(ch.rig.parents)) for c, ch in zip(cases, chars)]  # bad rows: before any call
        gt_mask = GT_MASK_TAG in getattr(call, "method_tags", ())
        requests = []
        for c, ch in zip(cases, chars):
            k = len(ch.rig.parents)
            extras = {"apparel_vertex_mask": np.asarray(ch.record.apparel_vertex_mask, bool)} if gt_mask else {}
            requests.append(MotionRequest(ch.rig, np.asarray(c.source_transforms, np.float32).reshape(-1, k, 7),
                                          ~np.asarray(ch.record.apparel_bone_mask, bool),
                                          float(data.motion_fps.get(c.motion_id, DEFAULT_FPS)), c.case_id, extras))
        answers = call(requests)
        out = []
        for c, ch, b, (pred, err, sec) in zip(cases, chars, burn, answers):
            if err:
                out.append(Outcome(c, "failed", err, sec))
                continue
            k = len(ch.rig.parents)
            truth = data.posed(ch, np.asarray(c.target_transforms, np.float32).reshape(-1, k, 7))
            pred = pred[b:]  # the burn-in frames are the method's to use, not scored
            metrics = apparel_scores(pred, truth, ch.record.apparel_vertex_mask, data.frame(ch))
            metrics |= self.motion_scores(ch, pred, truth, np.asarray(c.target_transforms, np.float64).reshape(-1, k, 7),
                                          float(data.motion_fps.get(c.motion_id, DEFAULT_FPS)), data.frame(ch).height)
            out.append(Outcome(c, "ok", None, sec, metrics, {"forward": pred[len(pred) // 2]}))
        return out
