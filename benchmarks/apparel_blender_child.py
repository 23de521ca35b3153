"""Blender's route for the apparel benchmark, run in a child process (bpy only, numpy).

    python benchmarks/apparel_blender_child.py IN.npz OUT.npz

IN holds the scene of benchmarks/apparel.py in the dataset frame (Y up): ``torso_box`` (2, 3)
corners, ``torso_head`` (3,), ``torso_yaw`` (F,) and ``torso_shift`` (F, 3) per frame, ``heads``
(L, 3), ``parents`` (L,) (-1: on the torso) and ``chain_of`` (L,) of the links, ``length`` (a
capsule's cylinder, head to tail), ``radius``, ``mass``, ``linear_damping``, ``angular_damping``,
``swing``, ``twist``, ``stiffness`` and ``damping`` (L, 3) per joint axis (swing x, y, twist z),
``gravity``, ``fps``, ``substeps``, ``iterations``. The route is MMDMC's: one active rigid body
(capsule) per link, a Generic Spring constraint per joint (angle limits and angular springs, as
mmd_tools builds from a PMX), the torso a kinematic passive body keyed every frame, and the
rigid-body cache baked over the clip. As in the stage, links collide with the torso but not with
other chains: the torso is in all 20 collision collections, chain c in collection c mod 20 only,
so neighbouring chains never share one. OUT holds ``bake_seconds`` and ``build_seconds``.
"""
import math
import sys
import time

import bpy  # noqa: I001
import numpy as np


def to_blender(p):
    """Dataset frame (Y up) -> Blender (Z up): (x, y, z) -> (x, -z, y)."""
    return (float(p[0]), float(-p[2]), float(p[1]))


def select_only(obj):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj


def main(inp, out):
    d = np.load(inp)
    start = time.process_time()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    frames = len(d["torso_yaw"])
    scene.frame_start, scene.frame_end = 1, frames
    scene.render.fps = int(d["fps"])
    bpy.ops.rigidbody.world_add()
    world = scene.rigidbody_world
    world.substeps_per_frame = int(d["substeps"])
    world.solver_iterations = int(d["iterations"])
    scene.gravity = (0.0, 0.0, -float(d["gravity"]))
    world.point_cache.frame_start, world.point_cache.frame_end = 1, frames
    lo, hi = d["torso_box"]
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    torso = bpy.context.active_object
    torso.scale = to_blender(hi - lo)
    torso.scale = (abs(torso.scale[0]), abs(torso.scale[1]), abs(torso.scale[2]))
    head = d["torso_head"]
    bpy.ops.rigidbody.object_add(type="PASSIVE")
    torso.rigid_body.kinematic = True
    torso.rigid_body.collision_collections = [True] * 20
    centre = 0.5 * (lo + hi)
    for f in range(frames):
        yaw = float(d["torso_yaw"][f])
        rel = centre - head
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([c * rel[0] + s * rel[2], rel[1], -s * rel[0] + c * rel[2]])
        torso.location = to_blender(head + rot + d["torso_shift"][f])
        torso.rotation_euler = (0.0, 0.0, yaw)  # about Blender's Z, the dataset's Y
        torso.keyframe_insert("location", frame=f + 1)
        torso.keyframe_insert("rotation_euler", frame=f + 1)
    links = []
    length, radius = float(d["length"]), float(d["radius"])
    for i, h in enumerate(d["heads"]):  # the capsule's full length is its cylinder plus two caps
        bpy.ops.mesh.primitive_cylinder_add(vertices=8, radius=radius, depth=length + 2 * radius)
        link = bpy.context.active_object
        link.location = to_blender(h + np.array([0.0, -length / 2, 0.0]))  # links hang down (-Y)
        bpy.ops.rigidbody.object_add(type="ACTIVE")
        link.rigid_body.collision_shape = "CAPSULE"
        link.rigid_body.mass = float(d["mass"])
        link.rigid_body.linear_damping = float(d["linear_damping"])
        link.rigid_body.angular_damping = float(d["angular_damping"])
        link.rigid_body.collision_collections = [c == int(d["chain_of"][i]) % 20 for c in range(20)]
        links.append(link)
    swing, twist = float(d["swing"]), float(d["twist"])
    for i, (h, p) in enumerate(zip(d["heads"], d["parents"])):
        bpy.ops.object.empty_add(location=to_blender(h))
        joint = bpy.context.active_object
        bpy.ops.rigidbody.constraint_add(type="GENERIC_SPRING")
        con = joint.rigid_body_constraint
        con.object1 = torso if p < 0 else links[p]
        con.object2 = links[i]
        con.disable_collisions = True
        con.spring_type = "SPRING2"  # stiffness in N m/rad, damping in N m s/rad
        for n, (axis, lim) in enumerate((("x", swing), ("y", swing), ("z", twist))):
            setattr(con, f"use_limit_ang_{axis}", True)
            setattr(con, f"limit_ang_{axis}_lower", -lim)
            setattr(con, f"limit_ang_{axis}_upper", lim)
            setattr(con, f"use_spring_ang_{axis}", True)
            setattr(con, f"spring_stiffness_ang_{axis}", float(d["stiffness"][i, n]))
            setattr(con, f"spring_damping_ang_{axis}", float(d["damping"][i, n]))
        for axis in "xyz":
            setattr(con, f"use_limit_lin_{axis}", True)
            setattr(con, f"limit_lin_{axis}_lower", 0.0)
            setattr(con, f"limit_lin_{axis}_upper", 0.0)
    built = time.process_time() - start
    start, start_wall = time.process_time(), time.perf_counter()
    with bpy.context.temp_override(scene=scene, point_cache=world.point_cache):
        bpy.ops.ptcache.bake(bake=True)
    baked, baked_wall = time.process_time() - start, time.perf_counter() - start_wall
    if not world.point_cache.is_baked:
        raise RuntimeError("Blender did not bake the rigid-body cache")
    np.savez(out, bake_seconds=baked, bake_wall_seconds=baked_wall, build_seconds=built)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
