"""A VMD motion played on an MMD model, as a dataset motion record.

Bone keys are matched to the model's bones by name: exactly, else by MMD's rule that a VMD name
holds only the first 15 bytes (Shift-JIS) of a longer bone name (the first such bone in file
order). Keys on one bone and frame that repeat keep the last one in the file. Each bone's
channels are sampled at every frame from 0 to the last key (30 fps) with MMD's Bezier curves
(:mod:`mimicbench.datagen.mmd.bezier`): translation per axis, rotation by slerp. Each frame is then posed
with grants and IK (:class:`mimicbench.datagen.mmd.pose.MMDPoser`) and converted to the dataset frame.
Show/IK keys switch IK bones off and on (:func:`ik_switches`). Morph keys are not used (the
dataset has no morph targets); their count is reported.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.ingest.clip_length import check_clip_frames
from mimicbench.datagen.mmd import frame
from mimicbench.datagen.mmd.bezier import bezier_weight, control_points
from mimicbench.datagen.mmd.model import MMDModel
from mimicbench.datagen.mmd.pose import MMDPoser
from mimicbench.datagen.mmd.vmd import VMDMotion
from mimicbench.geometry.quaternion import matrix_to_quat, quat_slerp
from mimicbench.schemas.motion import MotionRecord

VMD_FPS = 30.0


def _truncated(name: str) -> str:
    return name.encode("cp932", errors="replace")[:15].decode("cp932", errors="ignore")


def match_bones(track_names: list[str], model: MMDModel) -> tuple[dict[str, int], dict]:
    """Track name -> bone index (file order), and a report: ``matched``, ``matched_by_prefix``
    (names that matched only as MMD's 15-byte truncation), ``unmatched``."""
    exact = {}
    for i, b in enumerate(model.bones):
        exact.setdefault(b.name, i)
    prefix = {}
    for i, b in enumerate(model.bones):
        prefix.setdefault(_truncated(b.name), i)
    out, by_prefix, missing = {}, [], []
    for n in sorted(set(track_names)):
        if n in exact:
            out[n] = exact[n]
        elif n in prefix:
            out[n] = prefix[n]
            by_prefix.append(n)
        else:
            missing.append(n)
    return out, {"matched": len(out), "matched_by_prefix": by_prefix, "unmatched": missing}


def sample_channels(vmd: VMDMotion, model: MMDModel, num_frames: int | None = None, max_frames: int | None = None):
    """Animated local rotations (F, K, 4) (w, x, y, z) and translations (F, K, 3) of the model's
    bones (file order, file frame, MMD units) at frames 0..F-1, and the matching report."""
    k = len(model.bones)
    f = (vmd.last_frame + 1) if num_frames is None else num_frames
    f = check_clip_frames(f, f"VMD motion (last key at frame {vmd.last_frame})", max_frames)
    rot = np.zeros((f, k, 4))
    rot[..., 0] = 1.0
    trans = np.zeros((f, k, 3))
    mapping, report = match_bones(vmd.bone_names, model)
    names = np.array(vmd.bone_names, dtype=object)
    duplicates = 0
    frames_out = np.arange(f, dtype=np.float64)
    for name, bone in mapping.items():
        idx = np.flatnonzero(names == name)
        # sort by frame; for equal frames keep the last key in the file
        idx = idx[np.lexsort((idx, vmd.frames[idx]))]
        keep = np.r_[vmd.frames[idx][1:] != vmd.frames[idx][:-1], True]
        duplicates += int((~keep).sum())
        idx = idx[keep]
        kf = vmd.frames[idx].astype(np.float64)
        q = vmd.rotations[idx].astype(np.float64)[:, [3, 0, 1, 2]]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        p = vmd.positions[idx].astype(np.float64)
        seg = np.clip(np.searchsorted(kf, frames_out, side="right"), 1, max(len(kf) - 1, 1))
        if len(kf) == 1:
            rot[:, bone] = q[0]
            trans[:, bone] = p[0]
            continue
        f0, f1 = kf[seg - 1], kf[seg]
        u = np.clip((frames_out - f0) / np.maximum(f1 - f0, 1e-9), 0.0, 1.0)
        cp = np.stack([control_points(vmd.interpolation[i]) for i in idx])  # (n, 4 channels, 4)
        c = cp[seg]  # the curve stored on the later key shapes the segment
        w = np.stack([bezier_weight(u, c[:, ch, 0], c[:, ch, 1], c[:, ch, 2], c[:, ch, 3]) for ch in range(4)], axis=1)
        trans[:, bone] = p[seg - 1] + (p[seg] - p[seg - 1]) * w[:, :3]
        rot[:, bone] = quat_slerp(q[seg - 1], q[seg], w[:, 3])
    report["duplicate_keys"] = duplicates
    report["ignored_morph_keys"] = int(len(vmd.morph_frames))
    report["t0"], report["first_frame"] = 0.0, 0  # frame f is VMD frame f, at f / 30 s (FORMAT.md)
    return rot, trans, report


def ik_switches(vmd: VMDMotion, model: MMDModel, num_frames: int) -> tuple[np.ndarray, dict]:
    """(F, K) bool: whether each IK bone (file order) solves at frames 0..F-1, from the show/IK
    keys: a key holds from its frame until the next key that names the bone (MMD steps these
    keys, no interpolation); before its first key an IK bone is on. Report: ``ik_keys`` (count),
    ``ik_off_frames`` ({IK bone: frames off}), ``ik_unmatched`` (named IK bones the model lacks
    or that are not IK bones)."""
    on = np.ones((num_frames, len(model.bones)), bool)
    index = {b.name: i for i, b in enumerate(model.bones) if b.ik is not None}
    unmatched = set()
    order = np.argsort(vmd.ik_frames, kind="stable")  # equal frames: the later key in the file wins
    for k in order:
        start = int(vmd.ik_frames[k])
        for name, enabled in vmd.ik_states[k].items():
            if name not in index:
                unmatched.add(name)
            elif start < num_frames:
                on[start:, index[name]] = enabled
    off = {model.bones[i].name: int((~on[:, i]).sum()) for i in index.values() if (~on[:, i]).any()}
    return on, {"ik_keys": int(len(vmd.ik_frames)), "ik_off_frames": off, "ik_unmatched": sorted(unmatched)}


def pose_clip(vmd: VMDMotion, model: MMDModel, num_frames: int | None = None, chunk: int = 512,
              max_frames: int | None = None):
    """Global rotations (F, K, 3, 3) and bone heads (F, K, 3) in the file's frame, and the report
    (frames posed ``chunk`` at a time; IK bones switched off by show/IK keys do not solve)."""
    rot, trans, report = sample_channels(vmd, model, num_frames, max_frames)
    ik_on, ik_report = ik_switches(vmd, model, len(rot))
    report.update(ik_report)
    poser = MMDPoser(model)
    R = np.empty(rot.shape[:2] + (3, 3))
    t = np.empty(rot.shape[:2] + (3,))
    for s in range(0, len(rot), chunk):
        R[s:s + chunk], t[s:s + chunk] = poser.evaluate(rot[s:s + chunk], trans[s:s + chunk], ik_on[s:s + chunk])
    return R, t, report


def motion_from_vmd(vmd: VMDMotion, model: MMDModel, character, name: str, source: str = "",
                    scale: float = frame.MMD_UNIT_METRES, max_frames: int | None = None) -> tuple[MotionRecord, dict]:
    """The motion record of ``vmd`` on ``character`` (the record of ``model``; bones in its order),
    in the dataset frame, and the matching report.

    Raises:
        ClipTooLong: the clip (frames 0 to the last key) has more than ``max_frames`` frames
            (default :data:`mimicbench.datagen.ingest.clip_length.MAX_CLIP_FRAMES`); checked before sampling.
    """
    R, t, report = pose_clip(vmd, model, max_frames=max_frames)
    order = np.asarray(character.meta["mmd"]["file_bone_index"])
    q = frame.quat(matrix_to_quat(R[:, order]))
    p = frame.point(t[:, order], scale)
    transforms = np.concatenate([q, p], axis=-1).astype(np.float32)
    rec = MotionRecord(f"{character.character_id}/{name}", character.character_id, name, character.split, VMD_FPS,
                       len(transforms), len(order), transforms, source)
    return rec, report
