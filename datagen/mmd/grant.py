"""Grant (付与, "additional transform"): a bone takes a share of another bone's rotation and/or
translation, e.g. 腕捩連 turns with half of 腕捩, 目 with 0.15 of 両目. As MMD players do it (Saba's
``MMDNode::UpdateAppendTransform``):

- the source is the grant parent's animated rotation (its own granted share instead, when the
  parent is itself a grant bone and the grant is not "local"), with the parent's IK rotation in
  front when the parent is an IK link;
- the share is ``slerp(identity, source, ratio)`` (a negative ratio turns the other way);
- translation: the parent's animated translation (or its granted one), times the ratio.
"""
from __future__ import annotations

from mimicbench.datagen.mmd.model import BONE_GRANT_LOCAL
from mimicbench.geometry.quaternion import IDENTITY, quat_multiply, quat_slerp


def apply_grant(poser, i: int) -> None:
    """Set ``poser.grant_rot[:, i]``/``grant_trans[:, i]`` (all frames) from bone i's grant parent,
    then update its local transform (the caller updates globals)."""
    b = poser.model.bones[i]
    g = b.grant_parent
    parent = poser.model.bones[g]
    local = bool(b.flags & BONE_GRANT_LOCAL)
    parent_granted = parent.grant_rotation or parent.grant_translation
    if b.grant_rotation:
        src = poser.anim_rot[:, g] if local or not parent_granted else poser.grant_rot[:, g]
        if poser.is_ik_link[g]:
            src = quat_multiply(poser.ik_rot[:, g], src)
        poser.grant_rot[:, i] = quat_slerp(IDENTITY, src, float(b.grant_ratio))
    if b.grant_translation:
        src_t = poser.anim_trans[:, g] if local or not parent_granted else poser.grant_trans[:, g]
        poser.grant_trans[:, i] = src_t * float(b.grant_ratio)
    poser.update_local(i)
