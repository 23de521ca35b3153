"""Blender's route for the resample benchmark, run in a child process (bpy only, numpy).

    python benchmarks/resample_blender_child.py IN.npz OUT.npz

IN holds per character ``v{i}``, ``f{i}``, ``w{i}`` (dense weights) and ``target``. For each:
Decimate modifier (collapse, ratio = target / triangles, triangulated) on a copy, then a Data
Transfer modifier copying every vertex group from the original with face-interpolated mapping
(``POLYINTERP_NEAREST``), both applied. OUT holds the new ``v{i}``, ``f{i}``, ``w{i}`` and the
seconds Blender spent per character (``seconds``).
"""
import sys
import time

import bpy  # noqa: I001
import numpy as np


def make_object(name, v, f, w):
    me = bpy.data.meshes.new(name)
    me.from_pydata(v.tolist(), [], f.tolist())
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    for k in range(w.shape[1]):
        g = obj.vertex_groups.new(name=f"b{k}")
        for i in np.flatnonzero(w[:, k] > 0):
            g.add([int(i)], float(w[i, k]), "REPLACE")
    return obj


def route(v, f, w, target):
    src = make_object("src", v, f, w)
    start = time.perf_counter()
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
    seconds = time.perf_counter() - start
    me = dst.data
    nv = np.array([x.co[:] for x in me.vertices])
    me.calc_loop_triangles()
    nf = np.array([t.vertices[:] for t in me.loop_triangles])
    nw = np.zeros((len(nv), w.shape[1]))
    names = {g.index: int(g.name[1:]) for g in dst.vertex_groups}
    for x in me.vertices:
        for g in x.groups:
            nw[x.index, names[g.group]] = g.weight
    bpy.data.objects.remove(dst)
    bpy.data.objects.remove(src)
    return nv, nf, nw, seconds


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    d = np.load(sys.argv[1])
    n = int(d["count"])
    out, secs = {}, []
    for i in range(n):
        nv, nf, nw, s = route(d[f"v{i}"], d[f"f{i}"], d[f"w{i}"], int(d["target"]))
        out[f"v{i}"], out[f"f{i}"], out[f"w{i}"] = nv, nf, nw
        secs.append(s)
    np.savez(sys.argv[2], seconds=np.array(secs), **out)


main()
