"""Blender's route for the resample benchmark, run in a child process (bpy only, numpy).

    python benchmarks/resample_blender_child.py IN.npz OUT.npz

IN holds per character ``v{i}``, ``f{i}``, sparse weights ``wi{i}`` / ``wv{i}`` (N, 8) and
``target``. For each character the route is what a Blender-based stage does with a record:
build the mesh and its vertex groups (``foreach_set`` for coordinates and faces, one
``VertexGroup.add`` per influence, the only way in), copy it, apply a Decimate modifier
(collapse, ratio = target / triangles, triangulated) and a Data Transfer modifier copying every
vertex group with face-interpolated mapping (``POLYINTERP_NEAREST``), then read the new
coordinates, triangles and weights back. OUT holds the new ``v{i}``, ``f{i}``, dense ``w{i}``,
the seconds of the modifiers alone (``modifier_seconds``) and of the whole route
(``route_seconds``) per character.
"""
import sys
import time

import bpy  # noqa: I001
import numpy as np


def make_object(name, v, f, wi, wv):
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", np.ascontiguousarray(v, np.float32).ravel())
    me.loops.add(3 * len(f))
    me.loops.foreach_set("vertex_index", np.ascontiguousarray(f, np.int32).ravel())
    me.polygons.add(len(f))
    me.polygons.foreach_set("loop_start", np.arange(0, 3 * len(f), 3, dtype=np.int32))
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    groups = [obj.vertex_groups.new(name=f"b{k}") for k in range(int(wi.max()) + 1)]
    for i, (row_i, row_v) in enumerate(zip(wi.tolist(), wv.tolist())):
        for k, x in zip(row_i, row_v):
            if x > 0:
                groups[k].add([i], x, "REPLACE")
    return obj


def read_back(obj, num_groups):
    me = obj.data
    nv = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", nv)
    me.calc_loop_triangles()
    nf = np.empty(3 * len(me.loop_triangles), np.int32)
    me.loop_triangles.foreach_get("vertices", nf)
    nw = np.zeros((len(me.vertices), num_groups))
    names = {g.index: int(g.name[1:]) for g in obj.vertex_groups}
    for x in me.vertices:
        for g in x.groups:
            nw[x.index, names[g.group]] = g.weight
    return nv.reshape(-1, 3).astype(np.float64), nf.reshape(-1, 3), nw


def route(v, f, wi, wv, target):
    start = time.perf_counter()
    src = make_object("src", v, f, wi, wv)
    modifiers_start = time.perf_counter()
    dst = src.copy()
    dst.data = src.data.copy()
    bpy.context.scene.collection.objects.link(dst)
    dec = dst.modifiers.new("dec", "DECIMATE")
    dec.ratio = min(1.0, target / len(f))
    dec.use_collapse_triangulate = True
    bpy.context.view_layer.objects.active = dst
    bpy.ops.object.modifier_apply(modifier="dec")
    dt = dst.modifiers.new("dt", "DATA_TRANSFER")
    dt.object = src
    dt.use_vert_data = True
    dt.data_types_verts = {"VGROUP_WEIGHTS"}
    dt.vert_mapping = "POLYINTERP_NEAREST"
    dt.layers_vgroup_select_src = "ALL"
    dt.layers_vgroup_select_dst = "NAME"
    bpy.ops.object.modifier_apply(modifier="dt")
    modifier_seconds = time.perf_counter() - modifiers_start
    nv, nf, nw = read_back(dst, int(wi.max()) + 1)
    route_seconds = time.perf_counter() - start
    for obj in (dst, src):
        mesh = obj.data
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)
    return nv, nf, nw, modifier_seconds, route_seconds


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    d = np.load(sys.argv[1])
    out, modifier_seconds, route_seconds = {}, [], []
    for i in range(int(d["count"])):
        nv, nf, nw, m, r = route(d[f"v{i}"], d[f"f{i}"], d[f"wi{i}"], d[f"wv{i}"], int(d["target"]))
        out[f"v{i}"], out[f"f{i}"], out[f"w{i}"] = nv, nf, nw
        modifier_seconds.append(m)
        route_seconds.append(r)
    np.savez(sys.argv[2], modifier_seconds=np.array(modifier_seconds), route_seconds=np.array(route_seconds), **out)


main()
