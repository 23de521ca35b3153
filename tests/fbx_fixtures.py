"""FBX files for the tests, written by Blender in a child process (as the repo drives Blender).

- :func:`export_glb_as_fbx`: a shared glb with every clip as its own animation stack.
- :func:`write_rig_fbx`: a hand-made rig whose stacks animate the rig object itself (moving and
  scaling it) and whose mesh leaves vertices unweighted.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

# Blender's FBX exporter validates an action by its first slot (``act.fcurves``): glTF actions whose
# first slot drives shape keys are skipped, so the shape-key slots are removed first (LBS has no
# shape keys) and every clip becomes a stack named ``<armature>|<clip>``.
EXPORT_GLB = """
import bpy, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=sys.argv[-2])
for a in bpy.data.actions:
    for s in [s for s in a.slots if s.target_id_type != "OBJECT"]:
        a.slots.remove(s)
for o in bpy.context.scene.objects:
    if o.type == "MESH" and o.data.shape_keys:
        o.shape_key_clear()
bpy.ops.export_scene.fbx(filepath=sys.argv[-1], bake_anim=True, bake_anim_use_all_actions=True,
                         bake_anim_use_nla_strips=False, add_leaf_bones=False)
"""

# A three-bone rig (Blender Z up) and a tube around it, skinned by height; the top ring's 12
# vertices (and the cap's) have no weight. Stack "Bend" bends the bones; "Travel" moves, turns and
# scales the rig object (1 -> 1.5) while the middle bone turns; "Stretch" scales the rig object
# unevenly (x 1 -> 1.4). Keys at whole frames from 0 at 24 fps.
RIG = """
import bpy, bmesh, math, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = 24
arm_data = bpy.data.armatures.new("RigData")
rig = bpy.data.objects.new("Rig", arm_data)
scene.collection.objects.link(rig)
bpy.context.view_layer.objects.active = rig
bpy.ops.object.mode_set(mode="EDIT")
prev = None
for i, name in enumerate(["Root", "Mid", "Tip"]):
    b = arm_data.edit_bones.new(name)
    b.head, b.tail = (0, 0, 0.5 * i), (0, 0, 0.5 * (i + 1))
    if prev is not None:
        b.parent, b.use_connect = prev, True
    prev = b
bpy.ops.object.mode_set(mode="OBJECT")
mesh = bpy.data.meshes.new("TubeMesh")
bm = bmesh.new()
rings, seg = 13, 12
for r in range(rings):
    for s in range(seg):
        a = 2 * math.pi * s / seg
        bm.verts.new((0.15 * math.cos(a), 0.15 * math.sin(a), 1.6 * r / (rings - 1)))
bm.verts.ensure_lookup_table()
for r in range(rings - 1):
    for s in range(seg):
        v = [bm.verts[r * seg + s], bm.verts[r * seg + (s + 1) % seg],
             bm.verts[(r + 1) * seg + (s + 1) % seg], bm.verts[(r + 1) * seg + s]]
        bm.faces.new(v)
cap = bm.verts.new((0, 0, 1.75))
bm.verts.ensure_lookup_table()
for s in range(seg):
    bm.faces.new([bm.verts[(rings - 1) * seg + s], bm.verts[(rings - 1) * seg + (s + 1) % seg], cap])
bm.to_mesh(mesh)
tube = bpy.data.objects.new("Tube", mesh)
scene.collection.objects.link(tube)
tube.parent = rig
groups = {n: tube.vertex_groups.new(name=n) for n in ["Root", "Mid", "Tip"]}
for v in mesh.vertices:
    z = v.co.z
    if z > 1.55:
        continue  # the top ring and the cap: no weight
    for name, centre in (("Root", 0.25), ("Mid", 0.75), ("Tip", 1.25)):
        w = max(0.0, 1.0 - abs(z - centre) / 0.5)
        if w > 0:
            groups[name].add([v.index], w, "REPLACE")
tube.modifiers.new("Armature", "ARMATURE").object = rig
rig.animation_data_create()

def keyed(name, keys):
    action = bpy.data.actions.new(name)
    rig.animation_data.action = action
    for frame, values in keys:
        for target, prop, value in values:
            owner = rig if target is None else rig.pose.bones[target]
            if prop == "rotation_euler" and target is not None:
                owner.rotation_mode = "XYZ"
            setattr(owner, prop, value)
            owner.keyframe_insert(prop, frame=frame)
    rig.animation_data.action = None
    for pb in rig.pose.bones:
        pb.rotation_euler = (0, 0, 0)
    rig.location, rig.rotation_euler, rig.scale = (0, 0, 0), (0, 0, 0), (1, 1, 1)
    action.use_fake_user = True

keyed("Bend", [(0, [("Mid", "rotation_euler", (0, 0, 0)), ("Tip", "rotation_euler", (0, 0, 0))]),
               (20, [("Mid", "rotation_euler", (0.6, 0, 0)), ("Tip", "rotation_euler", (0.5, 0.3, 0))])])
keyed("Travel", [(0, [(None, "location", (0, 0, 0)), (None, "rotation_euler", (0, 0, 0)), (None, "scale", (1, 1, 1)),
                      ("Mid", "rotation_euler", (0, 0, 0))]),
                 (16, [(None, "location", (0.8, 0.3, 0.2)), (None, "rotation_euler", (0, 0, 1.2)),
                       (None, "scale", (1.5, 1.5, 1.5)), ("Mid", "rotation_euler", (0, 0.7, 0))])])
keyed("Stretch", [(0, [(None, "scale", (1, 1, 1)), ("Tip", "rotation_euler", (0, 0, 0))]),
                  (12, [(None, "scale", (1.4, 1, 1)), ("Tip", "rotation_euler", (0.4, 0, 0))])])
rig.animation_data.action = bpy.data.actions["Bend"]
bpy.ops.export_scene.fbx(filepath=sys.argv[-1], bake_anim=True, bake_anim_use_all_actions=True,
                         bake_anim_use_nla_strips=False, add_leaf_bones=False, bake_anim_simplify_factor=0.0)
"""
RIG_STACKS = {"Rig|Bend": 21, "Rig|Travel": 17, "Rig|Stretch": 13}  # stack -> frames (24 fps, keys from 0)
RIG_UNWEIGHTED = 13  # the top ring (12) and the cap


def _blender(script: str, *args) -> None:
    proc = subprocess.run([sys.executable, "-c", script, *map(str, args)], capture_output=True, text=True,
                          timeout=600)
    if proc.returncode != 0 or not Path(args[-1]).exists():
        raise RuntimeError(f"Blender child failed (exit {proc.returncode}): {proc.stderr[-2000:]}")


def export_glb_as_fbx(glb, fbx) -> Path:
    """Write ``fbx``: the glb's armature, meshes and every clip (one stack each)."""
    _blender(EXPORT_GLB, glb, fbx)
    return Path(fbx)


def write_rig_fbx(fbx, fps: int = 24, fps_base: float = 1.0) -> Path:
    """Write ``fbx``: the hand-made rig of :data:`RIG` with the stacks of :data:`RIG_STACKS`, keyed
    at whole frames of ``fps / fps_base`` (30 / 1.001: the 29.97 fps of video)."""
    _blender(RIG.replace("scene.render.fps = 24", f"scene.render.fps = {fps}; scene.render.fps_base = {fps_base!r}"), fbx)
    return Path(fbx)
