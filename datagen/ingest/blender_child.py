"""Runs inside a child process: import assets with Blender (bpy) and dump what ingest needs.

    python -m mimicbench.datagen.ingest.blender_child ASSET OUT.npz [OPTIONS_JSON]   one asset, then exit
    python -m mimicbench.datagen.ingest.blender_child --serve                        one asset per stdin line

``--serve`` reads one JSON job a line (``{"asset": ..., "out": ..., "options": {...}}``), resets
Blender to its factory state (empty scene) before each asset and prints ``DONE_MARKER OUT`` when
the job's result files are complete, so one Blender process ingests many assets. Each job writes
``OUT.npz`` (arrays) and then ``OUT.json`` (status, names, per-clip notes), both under temporary
names renamed when complete: a job that has ``OUT.json`` is finished. Only bpy, numpy, the
standard library and mimicbench's NumPy quaternions are imported here: bpy must be loaded before
libraries that bring their own Embree (pymeshlab), and a crash in Blender must not take the
parent with it.

Frames: Blender Z up is converted to the dataset's Y up, +Z forward by (x, y, z) -> (x, z, -y).
Bones: the armature's deform bones, parents before children. Rest mesh: every mesh deformed by
that armature (skinned, or rigidly attached to a bone), other modifiers applied ahead of the
armature, in world space at the rest pose, shape keys at their basis, triangulated.

glTF: every clip is first resampled at the frame times by the specification
(:mod:`mimicbench.datagen.ingest.gltf_resample`: slerp, STEP, CUBICSPLINE tangents, which Blender's
importer does not all honour), so Blender only reads keys. The armature's rest pose is the bind pose (from the inverse bind matrices, as linear blend
skinning needs: a rest pose other than the bind pose would blend multi-bone vertices wrongly);
the file's default pose (every node at its own TRS, glTF 2.0 section 3.5) is computed from the
file's JSON (:mod:`mimicbench.datagen.ingest.gltf_defaults`) and is the pose of every bone a clip does not
animate. Objects attached to a bone are moved to where the file places them (see
:func:`_fix_bone_children_offsets`).

Clips: every action (FBX: every animation stack, whose actions, one per animated object, play
together: :func:`_fbx_clips`), each sampled on its own: before a clip every pose bone goes back
to rest (the file's default pose), every object to the transform it was imported with, and the
clip's actions drive their objects through their own slots with no NLA, so a bone the clip does
not animate holds the default pose whatever clip came before. Animation of the armature object
itself is part of every bone's world matrix. Frame f of a clip is at file time ``t0 + f / fps``,
``t0`` the clip's first key in the file's own clock (:func:`_import`). Per frame and bone: the
rotation and symmetric stretch of the polar decomposition ``M = R U`` of the bone's world change
from rest, and the posed head position. Blender's mesh at two frames of each clip, for the
reproduction error, comes from a second import of the file (each clip from the file's defaults).

Unweighted vertices (no deform-bone weight) of a mesh hung from a bone follow that bone; those of
a mesh hung from no bone follow an object no joint carries, and are left out with their faces
(``left_out_vertices``); an asset whose every vertex is left out so fails, with the reason.
A mesh whose world transform mirrors (negative scale, determinant below 0) has its triangles'
winding turned, so faces point outward as Blender shows them.
"""
from __future__ import annotations

import json
import math
import os
import sys

import bpy  # noqa: I001  (first, before anything that loads another Embree)
import numpy as np

from mimicbench.datagen.ingest.clip_length import check_clip_frames  # standard library only
from mimicbench.datagen.ingest.job import DONE_MARKER  # standard library only
from mimicbench.geometry.quaternion import matrix_to_quat  # numpy only

C = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # Blender Z-up -> Y-up
# Below this a bone counts as rigid, and a clip whose bones all do stores no scale column: exports
# often carry scales like 0.99998 whose effect (under 0.01% of a bone's length) is not worth a column.
STRETCH_TOLERANCE = 1e-4


def _reset() -> None:
    """An empty scene with Blender's factory settings, auto-run scripts off."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.filepaths.use_scripts_auto_execute = False


def _import(path: str, options: dict, scratch: str) -> tuple[list[str], tuple[float, float]]:
    """Import ``path`` into the empty scene; returns notes (clips dropped by the glTF resampling)
    and the file's clock ``(frame_zero, key_rate)``: file time t is Blender frame
    ``frame_zero + t * key_rate``.

    glTF keys go to frame ``t * fps``; FBX is imported with ``anim_offset=0`` (Blender's default
    shifts every key one frame late) and its keys go to frame ``t * scene.render.fps``, the whole
    rate the importer converts with (the scene's own rate, ``fps / fps_base``, may be 29.97); a BVH's
    frame i goes to Blender frame ``1 + i`` (its importer starts at frame 1 at the least); a .blend
    keeps Blender's own clock (frame F at ``F / fps``).
    """
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        from mimicbench.datagen.ingest.gltf_resample import load_gltf, resampled_document, write_glb

        scene = bpy.context.scene
        doc, buffers = load_gltf(path)
        moving = {a.get("name", f"animation {i}") for i, a in enumerate(doc.get("animations", []))
                  if any(c["target"].get("path") in ("translation", "rotation", "scale") for c in a["channels"])}
        dropped = [a.get("name", f"animation {i}") for i, a in enumerate(doc.get("animations", []))
                   if a.get("name", f"animation {i}") not in moving]
        doc, blob = resampled_document(doc, buffers, scene.render.fps / scene.render.fps_base,
                                       options.get("max_clip_frames"))
        write_glb(scratch, doc, blob)
        try:
            bpy.ops.import_scene.gltf(filepath=scratch, bone_heuristic="BLENDER", guess_original_bind_pose=True)
        finally:
            os.remove(scratch)
        _fix_bone_children_offsets()
        return dropped, (0.0, _scene_fps(scene))
    elif ext == ".fbx":
        bpy.ops.import_scene.fbx(filepath=path, anim_offset=0.0)
        return [], (0.0, float(bpy.context.scene.render.fps))
    elif ext == ".bvh":
        bpy.ops.import_anim.bvh(filepath=path, global_scale=float(options.get("bvh_scale", 0.01)), frame_start=1,
                                update_scene_fps=True, update_scene_duration=True)
        return [], (1.0, _scene_fps(bpy.context.scene))
    elif ext == ".obj":
        bpy.ops.wm.obj_import(filepath=path)
    elif ext == ".blend":
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=False)
        bpy.context.preferences.filepaths.use_scripts_auto_execute = False
    else:
        raise ValueError(f"unsupported file type {ext!r}; expected .glb, .gltf, .fbx, .bvh, .obj or .blend")
    return [], (0.0, _scene_fps(bpy.context.scene))


def _scene_fps(scene) -> float:
    return scene.render.fps / scene.render.fps_base


def _fix_bone_children_offsets() -> None:
    """Place objects parented to a bone where the glTF file says.

    Blender hangs a bone's child from the bone's tail. The glTF importer (BLENDER heuristic)
    moves each such child back by the bone length it computed, then shortens the bone by the
    armature object's largest scale; so with an armature scaled by s, children sit
    ``length * (s - 1)`` too far along the bone. Undo that difference (object translations are
    in the bone's frame, in the armature's scaled units).
    """
    for obj in bpy.context.scene.objects:
        arm = obj.parent
        if obj.parent_type != "BONE" or arm is None or arm.type != "ARMATURE" or obj.parent_bone not in arm.data.bones:
            continue
        s = max(arm.scale)
        length = arm.data.bones[obj.parent_bone].length
        obj.location.y += length * (s - 1.0)
        rest = getattr(obj, "gltf2_animation_rest", None)
        if rest is not None:
            obj.gltf2_animation_rest = obj.matrix_basis.copy()


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
    """The bone an object hangs from rigidly (parented to a bone, directly or via other objects), or None."""
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
        mw = np.array(ev.matrix_world)
        chunks.append(co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3])
        ev.to_mesh_clear()
    return np.concatenate(chunks) @ C.T if chunks else np.zeros((0, 3))


def _rest_mesh(objs, bone_names, arm):
    """Rest vertices (N, 3), faces (M, 3), dense weights (N, K), per-object vertex counts and the
    number of vertices that had no deform-bone weight."""
    index = {n: i for i, n in enumerate(bone_names)}
    verts, faces, weights, counts, offset, unweighted = [], [], [], [], 0, 0
    for obj in objs:
        me = obj.data
        mw = np.array(obj.matrix_world)
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        me.calc_loop_triangles()
        tri = np.empty(len(me.loop_triangles) * 3, dtype=np.int64)
        me.loop_triangles.foreach_get("vertices", tri)
        if np.linalg.det(mw[:3, :3]) < 0:  # a mirroring transform (negative scale): Blender shows the faces
            tri = tri.reshape(-1, 3)[:, ::-1].reshape(-1)  # outward, so the winding turns with the vertices
        w = np.zeros((len(me.vertices), len(bone_names)), np.float32)
        attached = _attached_bone(obj, arm)
        while attached is not None and attached not in index:  # a non-deform bone: its deform ancestor
            parent = arm.data.bones[attached].parent
            attached = parent.name if parent is not None else None
        if not any(m.type == "ARMATURE" for m in obj.modifiers):
            if attached is not None:
                w[:, index[attached]] = 1.0  # rigid attachment
        else:
            groups = {g.index: g.name for g in obj.vertex_groups}
            for v in me.vertices:
                for g in v.groups:
                    name = groups.get(g.group)
                    if name in index and g.weight > 0:
                        w[v.index, index[name]] += g.weight
            loose = w.sum(axis=1) <= 0
            unweighted += int(loose.sum())
            if attached is not None:  # unweighted vertices of a bone-parented skinned mesh follow that bone
                w[loose, index[attached]] = 1.0
        verts.append(co)
        faces.append(tri.reshape(-1, 3) + offset)
        weights.append(w)
        counts.append(len(co))
        offset += len(co)
    return np.concatenate(verts) @ C.T, np.concatenate(faces), np.concatenate(weights), counts, unweighted


def _slot_for(action, obj):
    """The action slot that animates ``obj`` (Blender 4.4+ slotted actions), or None: the slot
    Blender already has ``obj`` use, else the one named after ``obj`` (``OB`` + its name, as the
    glTF importer names them). FBX actions, whose one slot is named after the action, are bound
    by :func:`_fbx_clips`."""
    slots = getattr(action, "slots", None)
    if not slots:
        return None
    for s in slots:
        if s.target_id_type == obj.id_type and any(u == obj for u in s.users()):
            return s
    for s in slots:
        if s.identifier == obj.id_type[:2] + obj.name:
            return s
    return None


def _channels(action, slot) -> list:
    """F-curves of ``action`` that ``slot`` plays (all of them for a legacy action)."""
    if slot is None or not hasattr(action, "layers"):
        return list(getattr(action, "fcurves", []))
    curves = []
    for layer in action.layers:
        for strip in layer.strips:
            bag = strip.channelbag(slot) if hasattr(strip, "channelbag") else None
            if bag is not None:
                curves.extend(bag.fcurves)
    return curves


def _fbx_clips(actions, scene) -> list[tuple[str, list]]:
    """One clip per FBX animation stack: ``(stack name, [(action, object, slot), ...])``.

    Blender's FBX importer makes one action per stack (and layer) and animated object, named
    ``<object>|<stack>`` (``<object>|<stack>|<layer>``), each with one slot of the object's ID type,
    and assigns only the first one to each object. The object is the one whose name prefixes the
    action's (the longest); actions of shape keys, materials or cameras drive no bone and are left
    out (LBS has no shape keys); an object's action whose name starts with no object's becomes a
    clip of its own that drives nothing (and so fails with a status row).
    """
    objects = sorted(scene.objects, key=lambda o: -len(o.name))
    clips: dict[str, list] = {}
    for action in actions:
        obj = next((o for o in objects if action.name.startswith(o.name + "|")), None)
        slots = [s for s in getattr(action, "slots", []) if s.target_id_type == "OBJECT"]
        if getattr(action, "slots", None) is not None and len(slots) != 1:
            continue
        if obj is None:  # an object's action named after no object: reported as a clip that drives no bone
            clips.setdefault(action.name, [])
            continue
        clips.setdefault(action.name[len(obj.name) + 1:], []).append((action, obj, slots[0] if slots else None))
    return list(clips.items())


def _action_clips(actions, objs) -> list[tuple[str, list]]:
    """One clip per action (glTF, .blend, BVH): ``(action name, [(action, object, slot), ...])``
    for every object the action has a slot for (a legacy action without slots: every object)."""
    out = []
    for action in actions:
        slots = getattr(action, "slots", None)
        if slots is None:
            bound = [(action, o, None) for o in objs if getattr(action, "id_root", "OBJECT") in ("OBJECT", "")]
        else:
            bound = [(action, o, s) for o in objs for s in [_slot_for(action, o)] if s is not None]
            ob_slots = [s for s in slots if s.target_id_type == "OBJECT"]
            arms = [o for o in objs if o.type == "ARMATURE"]
            if not bound and len(ob_slots) == 1 and len(arms) == 1:  # one object slot named otherwise: the rig's
                bound = [(action, arms[0], ob_slots[0])]
        out.append((action.name, bound))
    return out


def _bone_curves(bindings, arm) -> int:
    """How many F-curves of a clip's bindings drive pose bones of ``arm``."""
    return sum(fc.data_path.startswith("pose.bones[") for action, obj, slot in bindings if obj == arm
               for fc in _channels(action, slot))


def _stop_animation(scene) -> None:
    """No action, no NLA on any object; shape keys at their basis (LBS has no shape keys)."""
    for obj in scene.objects:
        ad = obj.animation_data
        if ad is not None:
            ad.action = None
            ad.use_nla = False
        if obj.type == "MESH" and obj.data.shape_keys:
            obj.data.shape_keys.animation_data_clear()
            for kb in obj.data.shape_keys.key_blocks:
                kb.value = 0.0


def _default_pose(arm, path: str) -> tuple[dict, int]:
    """Pose-bone values (location, quaternion, scale) of the file's default pose, by bone name,
    and how many bones took a value from the file (others stay at rest).

    glTF: each bone's armature-space matrix is its node's default world matrix brought into
    the armature's frame (the importer's BLENDER heuristic keeps node axes as bone axes, up to
    the Y-up to Z-up turn); the pose-bone basis follows from the rest matrices as Blender
    composes them (``P = P_parent @ R_parent^-1 @ R @ basis``). Other formats: the rest pose.
    """
    if os.path.splitext(path)[1].lower() not in (".glb", ".gltf"):
        return {}, 0
    from mimicbench.datagen.ingest.gltf_defaults import default_world_matrices
    from mimicbench.datagen.ingest.uris import gltf_json

    worlds = default_world_matrices(gltf_json(path))
    c4 = np.eye(4)
    c4[:3, :3] = C.T  # Y-up -> Blender Z-up
    to_arm = np.linalg.inv(np.array(arm.matrix_world)) @ c4
    target, values = {}, {}
    for b in arm.data.bones:  # parents before children
        rest = np.array(b.matrix_local)
        if b.name in worlds:
            target[b.name] = to_arm @ worlds[b.name]
        elif b.parent is not None and b.parent.name in target:  # no node: keeps its rest offset to the parent
            target[b.name] = target[b.parent.name] @ np.linalg.inv(np.array(b.parent.matrix_local)) @ rest
        else:
            target[b.name] = rest
        if b.parent is None:
            basis = np.linalg.inv(rest) @ target[b.name]
        else:
            prest = np.array(b.parent.matrix_local)
            basis = np.linalg.inv(rest) @ prest @ np.linalg.inv(target[b.parent.name]) @ target[b.name]
        values[b.name] = bpy_matrix(basis).decompose()
    return values, sum(b.name in worlds for b in arm.data.bones)


def bpy_matrix(m: np.ndarray):
    import mathutils

    return mathutils.Matrix([list(row) for row in m])


def _set_defaults(arm, scene, object_defaults, pose_defaults=None) -> None:
    """Every pose bone at the file's default pose (rest when none), every object at its imported transform."""
    pose_defaults = pose_defaults or {}
    for pb in arm.pose.bones:
        loc, rot, scale = pose_defaults.get(pb.name, ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
        pb.location = loc
        pb.rotation_quaternion = rot
        pb.rotation_euler = (0.0, 0.0, 0.0)
        pb.rotation_axis_angle = (0.0, 0.0, 1.0, 0.0)
        pb.scale = scale
    for obj in scene.objects:
        if obj.name in object_defaults:
            obj.matrix_basis = object_defaults[obj.name]


def _assign(bindings) -> None:
    """Let each ``(action, object, slot)`` of a clip drive its object (no NLA, full influence)."""
    for action, obj, slot in bindings:
        ad = obj.animation_data or obj.animation_data_create()
        ad.action = action
        if slot is not None:
            ad.action_slot = slot
        ad.use_nla = False
        ad.action_influence = 1.0


def _object_defaults(scene) -> dict:
    """Each object's transform as imported: glTF's importer stores the node's own TRS in
    ``gltf2_animation_rest`` (the pose the first clip may already have overwritten)."""
    out = {}
    for obj in scene.objects:
        rest = getattr(obj, "gltf2_animation_rest", None)
        if rest is not None and any(any(abs(x) > 0 for x in row) for row in rest):
            out[obj.name] = rest.copy()
        else:
            out[obj.name] = obj.matrix_basis.copy()
    return out


def _bone_matrices(arm, order: np.ndarray) -> np.ndarray:
    """(K, 4, 4) world matrices of the deform bones (``order`` indexes ``arm.pose.bones``)."""
    buf = np.empty(len(arm.pose.bones) * 16, np.float32)
    arm.pose.bones.foreach_get("matrix", buf)
    pose = buf.reshape(-1, 4, 4).transpose(0, 2, 1)[order].astype(np.float64)  # stored column-major
    return np.array(arm.matrix_world) @ pose


def pose_transforms(posed: np.ndarray, rest_inverse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame and bone the transform (..., K, 7) and stretch (..., K, 6) in the dataset frame.

    Args:
        posed: (..., K, 4, 4) bone world matrices (Blender frame).
        rest_inverse: (K, 4, 4) inverses of the bones' rest world matrices.

    The bone's world change ``M = posed @ rest^-1`` (3x3 part) is split by polar decomposition
    ``M = R U`` (R a proper rotation, U symmetric): R as a quaternion (w, x, y, z), U as
    ``s_xx, s_yy, s_zz, s_xy, s_xz, s_yz``; the translation is the posed head.
    """
    m = (posed @ rest_inverse)[..., :3, :3]
    rot, sym = m.copy(), np.broadcast_to(np.eye(3), m.shape).copy()
    gram = np.swapaxes(m, -1, -2) @ m
    scaled = (np.abs(gram - np.eye(3)).max(axis=(-1, -2)) > STRETCH_TOLERANCE) | (np.linalg.det(m) < 0)
    if scaled.any():  # the SVD only where the bone does not move rigidly
        u, s, vt = np.linalg.svd(m[scaled])
        flip = np.linalg.det(u @ vt) < 0  # a mirroring stays in the stretch; the rotation stays proper
        u[flip, :, -1] *= -1
        s[flip, -1] *= -1
        rot[scaled] = u @ vt
        sym[scaled] = np.swapaxes(vt, -1, -2) @ (s[..., None] * vt)
    r = C @ rot @ C.T
    st = C @ sym @ C.T
    out = np.concatenate([matrix_to_quat(r), posed[..., :3, 3] @ C.T], axis=-1)
    stretch = np.stack([st[..., 0, 0], st[..., 1, 1], st[..., 2, 2], st[..., 0, 1], st[..., 0, 2], st[..., 1, 2]], -1)
    return out, stretch


def _set_frame(scene, frame: float) -> None:
    scene.frame_set(int(math.floor(frame)), subframe=frame - math.floor(frame))


def _clip_frames(bindings, step: float) -> tuple[float, int]:
    """First frame (Blender frame, may be fractional) of a clip's actions and how many frames,
    ``step`` Blender frames apart, reach its last key."""
    ranges = [tuple(float(x) for x in action.frame_range) for action, _, _ in bindings]
    start, end = min(r[0] for r in ranges), max(r[1] for r in ranges)
    if abs(start - round(start)) < 1e-3:
        start = float(round(start))
    return start, int(math.floor((end - start) / step + 1e-3)) + 1


def _load(path: str, options: dict, scratch: str):
    """Reset Blender, import ``path`` and bring it to the state every clip starts from; returns a
    dict (``failed`` holds the reason when the file has no skeleton to ingest)."""
    _reset()
    dropped, clock = _import(path, options, scratch)
    scene = bpy.context.scene
    arms = [o for o in scene.objects if o.type == "ARMATURE"]
    if not arms:
        return {"failed": "no armature: the file has no skeleton to ingest"}
    arm = max(arms, key=lambda a: sum(b.use_deform for b in a.data.bones))
    bones = _deform_bones(arm)
    if not bones:
        return {"failed": f"armature {arm.name!r} has no deform bones"}
    _stop_animation(scene)
    object_defaults = _object_defaults(scene)
    _set_defaults(arm, scene, object_defaults)
    bpy.context.view_layer.update()
    pose_defaults, from_file = _default_pose(arm, path)
    meshes = _meshes_of(arm)
    if os.path.splitext(path)[1].lower() == ".fbx":  # the FBX importer links objects in no fixed order
        meshes.sort(key=lambda o: o.name)
    applied = _apply_other_modifiers(meshes)
    return {"failed": "", "scene": scene, "arm": arm, "bones": bones, "dropped": dropped, "clock": clock,
            "object_defaults": object_defaults, "pose_defaults": pose_defaults, "from_file": from_file,
            "meshes": meshes, "applied": applied, "actions": list(bpy.data.actions),
            "animatable": [o for o in scene.objects if o.name in object_defaults]}


def _clips_of(st: dict, path: str) -> list[tuple[str, list]]:
    """The clips of a loaded file: ``(name, [(action, object, slot), ...])`` (see :func:`_fbx_clips`)."""
    if os.path.splitext(path)[1].lower() == ".fbx" and any("|" in a.name for a in st["actions"]):
        return _fbx_clips(st["actions"], st["scene"])
    return _action_clips(st["actions"], st["animatable"])


def _start_clip(st: dict, bindings) -> None:
    """No animation, the file's default pose and objects' transforms, then ``bindings`` drive."""
    _stop_animation(st["scene"])
    _set_defaults(st["arm"], st["scene"], st["object_defaults"], st["pose_defaults"])
    _assign(bindings)


def _unplayed_curves(bindings, frame: float) -> int:
    """F-curves of the clip whose value at ``frame`` is not the value their object shows (a
    binding Blender does not play): the scene must be at ``frame``."""
    bad = 0
    for action, obj, slot in bindings:
        for fc in _channels(action, slot):
            try:
                value = obj.path_resolve(fc.data_path)
            except ValueError:
                continue  # a path of another object (a bone this rig lacks)
            shown = value[fc.array_index] if hasattr(value, "__len__") else value
            bad += abs(float(shown) - fc.evaluate(frame)) > 1e-4
    return bad


def _reproduce(path: str, options: dict, scratch: str, plan: list, mesh_names: list, keep: np.ndarray) -> dict:
    """Blender's own mesh at the evaluation frames of every planned clip, in a second import of the
    file (not the scene the clips were sampled in): each clip starts from the file's default pose
    (:func:`_start_clip`), and a clip whose check raised gets a fresh import for the next one.

    Args:
        plan: ``(clip name, [(action name, object name, slot identifier or None)], [Blender frames])``.
        mesh_names: the meshes, in the order of the stored vertices.
        keep: (N,) bool, the stored vertices among the meshes' vertices.

    Returns:
        clip name -> ((E, N', 3) evaluated vertices of the kept vertices, F-curves not played), or
        an error string for the clip.
    """
    out, st = {}, None
    for name, refs, frames in plan:
        try:
            if st is None:
                st = _load(path, options, scratch)
                if st["failed"]:
                    raise RuntimeError(st["failed"])
                st["arm"].data.pose_position = "POSE"
            objects = {o.name: o for o in st["scene"].objects}
            meshes = [objects[n] for n in mesh_names]  # in the first import's order
            bindings = []
            for action_name, obj_name, slot_id in refs:
                action = bpy.data.actions[action_name]
                slot = next(s for s in action.slots if s.identifier == slot_id) if slot_id is not None else None
                bindings.append((action, objects[obj_name], slot))
            _start_clip(st, bindings)
            evaluated, unplayed = [], 0
            for frame in frames:
                _set_frame(st["scene"], frame)
                evaluated.append(_evaluated_world_vertices(meshes)[keep])
                unplayed += _unplayed_curves(bindings, frame)
            out[name] = (np.stack(evaluated), unplayed)
        except Exception as exc:  # this clip's check failed; the clip is reported
            out[name] = f"{type(exc).__name__}: {exc}"
            st = None
    return out


def ingest_one(path: str, out_npz: str, options: dict | None = None) -> dict:
    """Import one asset into the (reset) scene and write its arrays to ``out_npz``; returns the
    result dict that :func:`run_job` writes as JSON.

    Every clip is sampled in this scene; Blender's mesh at two of its frames (for
    ``reproduction_error``) comes from a second import of the file (:func:`_reproduce`),
    where every key curve of the clip must also show on its object, or the clip fails.
    """
    options = options or {}
    scratch = out_npz + ".resampled.glb"
    st = _load(path, options, scratch)
    if st["failed"]:
        return {"status": "failed", "reason": st["failed"]}
    scene, arm, bones, meshes = st["scene"], st["arm"], st["bones"], st["meshes"]
    names = [b.name for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = np.array([_deform_parent(b, index) for b in bones], np.int32)
    arm.data.pose_position = "REST"
    bpy.context.view_layer.update()
    mw = np.array(arm.matrix_world)
    rest_inverse = np.array([np.linalg.inv(mw @ np.array(b.matrix_local)) for b in bones])
    order = np.array([list(arm.pose.bones).index(arm.pose.bones[b.name]) for b in bones])
    keypoints = np.array([C @ (mw @ np.append(np.array(b.head_local), 1.0))[:3] for b in bones])
    unweighted = 0
    if meshes:
        verts, faces, weights, counts, unweighted = _rest_mesh(meshes, names, arm)
    else:
        verts, faces, weights, counts = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, len(names)), np.float32), []
    # vertices with no deform weight whose mesh hangs from no bone follow the mesh's object, which
    # no joint carries: they are left out of the stored mesh, with every face that uses them
    keep = weights.sum(axis=1) > 0
    if len(keep) and not keep.any():  # Blender shows such meshes unskinned: no joint moves them
        return {"status": "failed", "reason": f"no vertex of its {len(meshes)} skinned mesh(es) ({len(keep)} "
                                              f"vertices) has a skin weight above 0 on a bone: Blender shows the "
                                              f"mesh unskinned and no joint moves it, so no character can be "
                                              f"stored (weight the mesh, or parent it to a bone)"}
    source_vertex = np.concatenate([np.arange(c) for c in counts]) if counts else np.zeros(0, np.int64)
    owner = np.repeat(np.arange(len(counts)), counts)
    left_out = int((~keep).sum())
    if left_out:
        new_index = np.cumsum(keep) - 1
        faces = new_index[faces[keep[faces].all(axis=1)]]
        verts, weights, source_vertex = verts[keep], weights[keep], source_vertex[keep]
        counts = [int(c) for c in np.bincount(owner[keep], minlength=len(counts))]
    arm.data.pose_position = "POSE"
    _set_defaults(arm, scene, st["object_defaults"], st["pose_defaults"])
    bpy.context.view_layer.update()
    default_keypoints = _bone_matrices(arm, order)[:, :3, 3] @ C.T  # joints in the file's default pose
    fps = _scene_fps(scene)
    frame_zero, key_rate = st["clock"]
    step = key_rate / fps  # Blender frames per dataset frame
    arrays = {"vertices": verts, "faces": faces, "weights": weights, "keypoints": keypoints, "parents": parents,
              "default_keypoints": default_keypoints, "mesh_vertex_counts": np.array(counts, np.int64),
              "source_vertex": source_vertex.astype(np.int64)}
    clips, plan = [], []
    clip_errors = [{"name": n, "reason": "the clip animates only morph-target weights, no bone"} for n in st["dropped"]]
    for name, bindings in _clips_of(st, path):
        try:
            if _bone_curves(bindings, arm) == 0:
                clip_errors.append({"name": name, "reason": "the action animates no bone of the armature"})
                continue
            _start_clip(st, bindings)
            start, n = _clip_frames(bindings, step)
            n = check_clip_frames(n, f"clip {name!r}", options.get("max_clip_frames"))  # before allocating
            posed = np.zeros((n, len(bones), 4, 4))
            for obj in meshes:  # no mesh is needed to sample the bones
                obj.hide_viewport = True
            for f in range(n):
                _set_frame(scene, start + f * step)
                posed[f] = _bone_matrices(arm, order)
            for obj in meshes:
                obj.hide_viewport = False
            transforms, stretch = pose_transforms(posed, rest_inverse)
            ci = len(clips)
            arrays[f"clip{ci}_transforms"] = transforms
            identity = np.array([1.0, 1, 1, 0, 0, 0])
            if np.abs(stretch - identity).max() > STRETCH_TOLERANCE:
                arrays[f"clip{ci}_scale"] = stretch
            eval_at = sorted({n // 2, n - 1})
            arrays[f"clip{ci}_eval_frames"] = np.array(eval_at)
            first = start - frame_zero if step == 1 else (start - frame_zero) / step  # the file's frame of frame 0
            clips.append({"name": name, "frames": n, "fps": fps, "t0": first / fps, "first_frame": first,
                          "scaled": f"clip{ci}_scale" in arrays})
            refs = [(a.name, o.name, s.identifier if s is not None else None) for a, o, s in bindings]
            plan.append((name, refs, [start + f * step for f in eval_at]))
        except Exception as exc:  # one unreadable clip becomes a status row; the others go on
            clip_errors.append({"name": name, "reason": f"{type(exc).__name__}: {exc}"})
    _stop_animation(scene)
    result = {"status": "ok", "reason": "", "bone_names": names, "blender": bpy.app.version_string,
              "meshes": [o.name for o in meshes], "applied_modifiers": st["applied"],
              "unweighted_vertices": unweighted, "fps": fps, "default_pose_bones": st["from_file"]}
    if left_out:
        result["left_out_vertices"] = left_out
    checked = _reproduce(path, options, scratch, plan, [o.name for o in meshes], keep) if meshes and plan else {}
    kept_clips = []
    for ci, clip in enumerate(clips):
        check = checked.get(clip["name"])
        if isinstance(check, str) or (check is not None and check[1]):
            reason = check if isinstance(check, str) else (
                f"Blender does not play {check[1]} of the clip's key curves in a second import")
            clip_errors.append({"name": clip["name"], "reason": reason})
            for key in [k for k in arrays if k.startswith(f"clip{ci}_")]:
                del arrays[key]
            continue
        new = len(kept_clips)
        for key in [k for k in arrays if k.startswith(f"clip{ci}_")]:  # clips are renumbered in order
            arrays[f"clip{new}_" + key[len(f"clip{ci}_"):]] = arrays.pop(key)
        if check is not None:
            arrays[f"clip{new}_eval_vertices"] = check[0]
        kept_clips.append(clip)
    _save_npz(out_npz, arrays)
    result.update(clips=kept_clips, clip_errors=clip_errors)
    return result


def _save_npz(out_npz: str, arrays: dict) -> None:
    tmp = out_npz + ".part.npz"
    np.savez(tmp, **arrays)
    os.replace(tmp, out_npz)


def result_path(out_npz: str) -> str:
    return out_npz[: -len(".npz")] + ".json"


def run_job(path: str, out_npz: str, options: dict | None = None) -> dict:
    """Ingest one asset and write ``OUT.json`` (last, atomically); errors become a failed result."""
    try:
        result = ingest_one(path, out_npz, options)
    except Exception as exc:  # reported to the parent as a status row
        result = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
    final = result_path(out_npz)
    with open(final + ".part", "w") as f:
        json.dump(result, f)
    os.replace(final + ".part", final)
    return result


def serve(stdin=None, stdout=None) -> int:
    """Run jobs read as JSON lines from stdin until it closes; print ``DONE_MARKER out`` after each."""
    stdin = stdin or sys.stdin
    stdout = stdout or sys.stdout
    for line in stdin:
        if not line.strip():
            continue
        job = json.loads(line)
        run_job(job["asset"], job["out"], job.get("options"))
        stdout.write(f"\n{DONE_MARKER} {job['out']}\n")
        stdout.flush()
    return 0


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--serve"]:
        return serve()
    path, out_npz = argv[0], argv[1]
    run_job(path, out_npz, json.loads(argv[2]) if len(argv) > 2 else None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
