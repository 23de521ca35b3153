"""Runs inside a child process: import one asset with Blender (bpy) and dump what ingest needs.

    python -m datagen.ingest.blender_child ASSET OUT.npz

Writes ``OUT.npz`` (arrays) and ``OUT.json`` (status and names). Only bpy, numpy, the
standard library and mimicbench's NumPy quaternions are imported here: bpy must be loaded before libraries that bring their own
Embree (pymeshlab), and a crash in Blender must not take the parent with it.

Frames: Blender Z up is converted to the dataset's Y up, +Z forward by (x, y, z) -> (x, z, -y).
Bones: the armature's deform bones, parents before children. Rest mesh: every mesh deformed by
that armature (skinned, or rigidly attached to a bone), other modifiers applied ahead of the
armature, in world space at the rest pose, shape keys at their basis, triangulated.
Clips: every action, sampled at each frame of its range at the scene frame rate; per bone the
world rotation relative to rest and the posed head position.
"""
from __future__ import annotations

import json
import os
import sys
import time

import bpy  # noqa: I001  (first, before anything that loads another Embree)
import numpy as np

from mimicbench.quaternion import matrix_to_quat  # numpy only

C = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # Blender Z-up -> Y-up
EVAL_FRAMES_PER_CLIP = 3


def _import(path: str) -> None:
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".fbx":
        bpy.ops.import_scene.fbx(filepath=path)
    elif ext == ".bvh":
        bpy.ops.import_anim.bvh(filepath=path, update_scene_fps=True, update_scene_duration=True)
    elif ext == ".obj":
        bpy.ops.wm.obj_import(filepath=path)
    elif ext == ".blend":
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=False)
    else:
        raise ValueError(f"unsupported file type {ext!r}; expected .glb, .gltf, .fbx, .bvh, .obj or .blend")


def _apply_other_modifiers(objs) -> list[str]:
    """Apply every non-armature modifier into the mesh data, moved ahead of the armature first
    (so the stored rest mesh and weights are what the armature deforms). Returns what was applied;
    a modifier Blender refuses to apply (for example on a mesh with shape keys) is reported."""
    done = []
    for obj in objs:
        bpy.context.view_layer.objects.active = obj
        for mod in [m for m in obj.modifiers if m.type != "ARMATURE"]:
            name = mod.name
            try:
                bpy.ops.object.modifier_move_to_index(modifier=name, index=0)
                bpy.ops.object.modifier_apply(modifier=name)
                done.append(f"{obj.name}:{name}")
            except RuntimeError as exc:
                done.append(f"{obj.name}:{name} NOT applied ({str(exc).strip()[:80]})")
    return done


def _deform_bones(arm):
    bones = [b for b in arm.data.bones if b.use_deform]
    order, placed = [], set()
    while len(order) < len(bones):  # parents before children
        for b in bones:
            if b.name in placed:
                continue
            p = b.parent
            while p is not None and not p.use_deform:
                p = p.parent
            if p is None or p.name in placed:
                order.append(b)
                placed.add(b.name)
    return order


def _deform_parent(b, index):
    p = b.parent
    while p is not None and p.name not in index:
        p = p.parent
    return -1 if p is None else index[p.name]


def _attached_bone(obj, arm):
    """The bone an object hangs from rigidly (parented to a bone, directly or via empties), or None."""
    p = obj
    while p.parent is not None:
        if p.parent == arm:
            return p.parent_bone if p.parent_type == "BONE" and p.parent_bone else None
        p = p.parent
    return None


def _meshes_of(arm):
    """Meshes the armature drives: skinned (Armature modifier) or rigidly attached to a bone."""
    out = []
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        skinned = any(m.type == "ARMATURE" and m.object == arm for m in obj.modifiers)
        if skinned or _attached_bone(obj, arm):
            out.append(obj)
    return out


def _evaluated_world_vertices(objs):
    dg = bpy.context.evaluated_depsgraph_get()
    chunks = []
    for obj in objs:
        ev = obj.evaluated_get(dg)
        mesh = ev.to_mesh()
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3) @ np.array(ev.matrix_world)[:3, :3].T + np.array(ev.matrix_world)[:3, 3]
        chunks.append(co)
        ev.to_mesh_clear()
    return np.concatenate(chunks) @ C.T if chunks else np.zeros((0, 3))


def _rest_mesh(objs, bone_names, arm):
    index = {n: i for i, n in enumerate(bone_names)}
    verts, faces, weights, offset = [], [], [], 0
    for obj in objs:
        me = obj.data
        mw = np.array(obj.matrix_world)
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        me.calc_loop_triangles()
        tri = np.empty(len(me.loop_triangles) * 3, dtype=np.int64)
        me.loop_triangles.foreach_get("vertices", tri)
        w = np.zeros((len(me.vertices), len(bone_names)), np.float32)
        bone = _attached_bone(obj, arm)
        if bone is not None and not any(m.type == "ARMATURE" for m in obj.modifiers):
            b = arm.data.bones[bone]
            while b is not None and b.name not in index:
                b = b.parent
            w[:, index[b.name] if b is not None else 0] = 1.0  # rigid attachment
        else:
            groups = {g.index: g.name for g in obj.vertex_groups}
            for v in me.vertices:
                for g in v.groups:
                    name = groups.get(g.group)
                    if name in index and g.weight > 0:
                        w[v.index, index[name]] += g.weight
        verts.append(co)
        faces.append(tri.reshape(-1, 3) + offset)
        weights.append(w)
        offset += len(co)
    return np.concatenate(verts) @ C.T, np.concatenate(faces), np.concatenate(weights)


def _assign(arm, action):
    ad = arm.animation_data or arm.animation_data_create()
    ad.action = action
    slots = getattr(action, "slots", None)
    if slots and getattr(ad, "action_slot", None) is None:
        ad.action_slot = slots[0]


def _pose_transforms(arm, bones):
    mw = np.array(arm.matrix_world)
    out = np.zeros((len(bones), 7))
    for k, b in enumerate(bones):
        pb = arm.pose.bones[b.name]
        posed = mw @ np.array(pb.matrix)
        rest = mw @ np.array(b.matrix_local)
        delta = posed @ np.linalg.inv(rest)
        r = delta[:3, :3]
        u, _, vt = np.linalg.svd(r)  # drop any scale: nearest rotation
        r = u @ vt
        if np.linalg.det(r) < 0:
            r = u @ np.diag([1, 1, -1]) @ vt
        r = C @ r @ C.T
        head = C @ (posed[:3, 3])
        out[k, :4] = matrix_to_quat(r)
        out[k, 4:] = head
    return out


def ingest_one(path: str, out_npz: str) -> dict:
    hang = os.environ.get("MIMICBENCH_TEST_HANG")  # test hook: simulate an asset that hangs
    if hang and hang in os.path.basename(path):
        time.sleep(3600)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.filepaths.use_scripts_auto_execute = False
    _import(path)
    arms = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"]
    if not arms:
        return {"status": "failed", "reason": "no armature: the file has no skeleton to ingest"}
    arm = max(arms, key=lambda a: sum(b.use_deform for b in a.data.bones))
    bones = _deform_bones(arm)
    names = [b.name for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = np.array([_deform_parent(b, index) for b in bones], np.int32)
    meshes = _meshes_of(arm)
    applied = _apply_other_modifiers(meshes)
    for obj in meshes:  # morph targets at their basis: LBS has no shape keys
        if obj.data.shape_keys:
            for kb in obj.data.shape_keys.key_blocks:
                kb.value = 0.0
    actions = list(bpy.data.actions)
    arm.data.pose_position = "REST"
    bpy.context.view_layer.update()
    mw = np.array(arm.matrix_world)
    keypoints = np.array([C @ (mw @ np.append(np.array(b.head_local), 1.0))[:3] for b in bones])
    if meshes:
        verts, faces, weights = _rest_mesh(meshes, names, arm)
        loose = weights.sum(axis=1) <= 0  # vertices no deform bone weights: follow the nearest joint
        if loose.any():
            nearest = np.argmin(np.linalg.norm(verts[loose, None, :] - keypoints[None], axis=2), axis=1)
            weights[np.flatnonzero(loose), nearest] = 1.0
    else:
        verts, faces, weights = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, len(names)), np.float32)
    arm.data.pose_position = "POSE"
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    arrays = {"vertices": verts, "faces": faces, "weights": weights, "keypoints": keypoints, "parents": parents}
    clips = []
    for ci, action in enumerate(actions):
        _assign(arm, action)
        start, end = (int(round(x)) for x in action.frame_range)
        frames = list(range(start, end + 1))
        transforms = np.zeros((len(frames), len(bones), 7))
        eval_at = sorted({frames[0], frames[len(frames) // 2], frames[-1]})
        evaluated = []
        for fi, f in enumerate(frames):
            scene.frame_set(f)
            transforms[fi] = _pose_transforms(arm, bones)
            if meshes and f in eval_at:
                evaluated.append(_evaluated_world_vertices(meshes))
        arrays[f"clip{ci}_transforms"] = transforms
        arrays[f"clip{ci}_eval_frames"] = np.array([frames.index(f) for f in eval_at])
        if meshes:
            arrays[f"clip{ci}_eval_vertices"] = np.stack(evaluated)
        clips.append({"name": action.name, "frames": len(frames), "fps": fps})
    np.savez_compressed(out_npz, **arrays)
    return {"status": "ok", "reason": "", "bone_names": names, "clips": clips,
            "blender": bpy.app.version_string, "meshes": [o.name for o in meshes],
            "applied_modifiers": applied}


def main() -> int:
    path, out_npz = sys.argv[1], sys.argv[2]
    try:
        result = ingest_one(path, out_npz)
    except Exception as exc:  # reported to the parent as a status row
        result = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
    with open(out_npz[: -len(".npz")] + ".json", "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
