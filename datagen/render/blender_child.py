"""Runs inside a child process: render a job's meshes with Blender's Workbench engine.

    python -m mimicbench.datagen.render.blender_child JOB.json

``JOB.json`` names the meshes file (``.npz`` with ``v{i}`` (N, 3) float32 vertices in the
dataset frame and ``f{i}`` (M, 3) int32 faces), the image size, the cameras (fitted by
:func:`mimicbench.datagen.render.camera.fit_camera` in the parent) and, per panel, its mesh, colour, camera
and output PNG. Every panel renders in this one process (Blender starts once per job, not once
per mesh); each panel's PNG is written when done and ``JOB.result.json`` says which succeeded.
Images have a transparent background (RGBA). Like the ingest's child, only bpy, numpy and the
standard library are loaded, auto-run scripts are off, and a crash here cannot end the parent.
"""
from __future__ import annotations

import json
import sys
import time

import bpy  # noqa: I001  (first, before anything that loads another Embree)
import numpy as np

from mimicbench.datagen.ingest.blender_child import C  # Blender Z up -> dataset Y up; C.T is the way back


def _to_blender(v: np.ndarray) -> np.ndarray:
    """(..., 3) dataset-frame vectors to Blender's Z-up frame."""
    return np.asarray(v, np.float64) @ C


def _setup_scene(width: int, height: int):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.filepaths.use_scripts_auto_execute = False
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.view_settings.view_transform = "Standard"
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "OBJECT"
    shading.show_cavity = True
    shading.cavity_type = "WORLD"
    shading.show_object_outline = True
    shading.object_outline_color = (0.15, 0.15, 0.15)
    scene.display.render_aa = "8"
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type = "ORTHO"
    cam.data.sensor_fit = "AUTO"
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene, cam


def _add_mesh(scene, name: str, verts: np.ndarray, faces: np.ndarray, colour):
    mesh = bpy.data.meshes.new(name)
    vb = _to_blender(verts).astype(np.float32)
    mesh.vertices.add(len(vb))
    mesh.vertices.foreach_set("co", vb.ravel())
    f = np.asarray(faces, np.int32)
    mesh.loops.add(f.size)
    mesh.loops.foreach_set("vertex_index", f.ravel())
    mesh.polygons.add(len(f))
    mesh.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(f), 3, np.int32))
    mesh.update(calc_edges=True)
    mesh.validate()
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    obj.color = (*colour, 1.0)
    obj.hide_render = True
    scene.collection.objects.link(obj)
    return obj


def _place_camera(cam, spec: dict) -> None:
    from mathutils import Matrix

    rot = np.stack([_to_blender(spec["right"]), _to_blender(spec["up"]), _to_blender(spec["back"])], axis=1)
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = _to_blender(spec["location"])
    cam.matrix_world = Matrix(m.tolist())
    cam.data.ortho_scale = spec["ortho_scale"]
    cam.data.clip_start = spec["clip_start"]
    cam.data.clip_end = spec["clip_end"]


def render_job(job: dict) -> dict:
    """Render every panel of ``job``; returns ``{"status", "panels": [{"ok", "error"}], ...}``."""
    start = time.perf_counter()
    scene, cam = _setup_scene(int(job["width"]), int(job["height"]))
    meshes = np.load(job["meshes"])
    done = []
    for i, panel in enumerate(job["panels"]):
        try:
            obj = _add_mesh(scene, f"panel{i}", meshes[f"v{panel['mesh']}"], meshes[f"f{panel['mesh']}"],
                            panel["colour"])
            _place_camera(cam, job["cameras"][panel["camera"]])
            obj.hide_render = False
            scene.render.filepath = panel["out"]
            bpy.ops.render.render(write_still=True)
            obj.hide_render = True
            bpy.data.objects.remove(obj)
            done.append({"ok": True, "error": None})
        except Exception as exc:  # one bad panel does not lose the others
            done.append({"ok": False, "error": f"{type(exc).__name__}: {exc}"})
    return {"status": "ok", "panels": done, "blender": bpy.app.version_string,
            "seconds": time.perf_counter() - start}


def main() -> int:
    job_file = sys.argv[1]
    try:
        with open(job_file) as f:
            result = render_job(json.load(f))
    except Exception as exc:  # reported to the parent
        result = {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
    with open(job_file[: -len(".json")] + ".result.json", "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
