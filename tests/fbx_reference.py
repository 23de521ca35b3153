"""An FBX reader that never touches Blender: ufbx (the official bindings of the ufbx C library)
evaluates a file's animation stacks and skins its meshes, for the tests to compare ingest with.

ufbx 0.0.5's bindings drop references: freeing a wrapper they returned (a node, a mesh, a list,
a stack) releases what it never retained, so a temporary ``nodes[i].name`` is enough for the
next ``nodes[i]`` to crash, and so is the interpreter's own teardown of a scene's elements. So
every scene, evaluated scene, list and element this module takes is held in :data:`_HELD`, never
taken as a temporary, and never freed: the reader runs in a child process
(:func:`ufbx_vertices`) that leaves by ``os._exit`` once its results are written.

Frame: ufbx converts the file to metres and right-handed Y up, +Z forward (the dataset's frame).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import ufbx

_HELD: list = []  # every ufbx object this module ever took (see the module docstring)


class FbxReference:
    """One FBX file as ufbx reads it.

    Args:
        path: the .fbx file.
    """

    def __init__(self, path):
        self.scene = self._hold(ufbx.load_file(str(path), target_axes=ufbx.axes_right_handed_y_up,
                                               target_unit_meters=1.0))
        self._stacks = self._list(self.scene.anim_stacks)
        self._nodes = self._list(self.scene.nodes)
        self.stack_names = [s.name for s in self._stacks]
        self.node_names = [n.name for n in self._nodes]
        settings = self._hold(self.scene.settings)
        self.fps = float(settings.frames_per_second)

    def _hold(self, obj):
        """Keep ``obj`` alive until the process ends (see the module docstring)."""
        _HELD.append(obj)
        return obj

    def _list(self, elements) -> list:
        """Every element of a ufbx list, each held."""
        self._hold(elements)
        return [self._hold(e) for e in list(elements)]

    def stack_range(self, name: str) -> tuple[float, float]:
        """(begin, end) seconds of the stack named ``name``."""
        stack = self._stacks[self.stack_names.index(name)]
        return float(stack.time_begin), float(stack.time_end)

    def node_index(self, blender_names) -> list[int]:
        """Index into the file's nodes of the node each Blender object name came from (Blender adds
        ``.001``-style suffixes when names collide)."""
        out = []
        for name in blender_names:
            match = name if name in self.node_names else re.sub(r"\.\d{3}$", "", name)
            out.append(self.node_names.index(match))
        return out

    def vertices(self, stack: str | None, time: float, nodes: list[int]) -> list[np.ndarray]:
        """World positions (metres) of each listed mesh node's vertices: ufbx's own skinning of
        the stack named ``stack`` at ``time`` seconds of the file, or the file's default
        (unanimated) scene when ``stack`` is None.

        Returns:
            per node a (V, 3) float64 array, vertices in the file's order (FBX control points).
        """
        if stack is None:
            scene = self.scene
        else:
            anim = self._hold(self._stacks[self.stack_names.index(stack)].anim)
            scene = self._hold(ufbx.evaluate_scene(self.scene, anim, float(time), evaluate_skinning=True))
        all_nodes = self._list(scene.nodes)
        out = []
        for i in nodes:
            mesh = self._hold(all_nodes[i].mesh)
            if stack is None:
                pos, local = np.array(self._hold(mesh.vertices), np.float64), True
            else:
                skinned = self._hold(mesh.skinned_position)
                pos, local = np.array(self._hold(skinned.values), np.float64), mesh.skinned_is_local
            if local:  # geometry_to_world: columns x, y, z axes and origin
                m = np.array(self._hold(all_nodes[i].geometry_to_world), np.float64)
                pos = pos @ m[:3] + m[3]
            out.append(pos)
        return out


def ufbx_vertices(path, meshes, times: dict, loads: int = 1, timeout: float = 600) -> dict:
    """ufbx's world vertices of Blender's mesh objects ``meshes`` (names, the ingest's
    ``meshes``) at the given times of each stack, read in a child process.

    Args:
        times: stack name -> seconds.
        loads: load the file this many times and check every load reads the same (a reader that
            leaks or drops references crashes or differs on a later load).

    Returns:
        ``{"rest": [per mesh (V, 3)], stack: (T, sum V, 3) float64 in the order of ``meshes``,
        "counts": [V per mesh], "stacks": [every stack name], "fps": file rate}``.
    """
    out = Path(str(path) + f".ufbx-{os.getpid()}.npz")
    request = json.dumps({"meshes": list(meshes), "times": {k: list(map(float, v)) for k, v in times.items()},
                          "loads": loads})
    proc = subprocess.run([sys.executable, "-m", "tests.fbx_reference", str(path), request, str(out)],
                          capture_output=True, text=True, timeout=timeout, cwd=Path(__file__).resolve().parents[1])
    if proc.returncode != 0 or not out.exists():
        raise RuntimeError(f"ufbx child failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
    with np.load(out) as d:
        arrays = {k: d[k] for k in d.files}
    out.unlink()
    info = json.loads(str(arrays.pop("info")))
    counts = info["counts"]
    rest = np.split(arrays.pop("rest"), np.cumsum(counts)[:-1])
    result = {"rest": rest, "counts": counts, "stacks": info["stacks"], "fps": info["fps"]}
    for i, name in enumerate(times):
        result[name] = arrays[f"stack{i}"]
    return result


def _child(path: str, request: str, out: str) -> None:
    req = json.loads(request)
    first = None
    for _ in range(int(req["loads"])):
        ref = FbxReference(path)
        nodes = ref.node_index(req["meshes"])
        rest = ref.vertices(None, 0.0, nodes)
        arrays = {"rest": np.concatenate(rest) if rest else np.zeros((0, 3))}
        for i, (name, ts) in enumerate(req["times"].items()):
            arrays[f"stack{i}"] = np.stack([np.concatenate(ref.vertices(name, t, nodes)) for t in ts]) if ts \
                else np.zeros((0, len(arrays["rest"]), 3))
        if first is None:
            first = arrays
        elif any(not np.array_equal(first[k], arrays[k]) for k in first):
            raise SystemExit("a later load of the file read differently")
    info = {"counts": [len(r) for r in rest], "stacks": ref.stack_names, "fps": ref.fps}
    np.savez(out + ".part.npz", info=json.dumps(info), **first)
    os.replace(out + ".part.npz", out)


if __name__ == "__main__":
    _child(*sys.argv[1:4])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)  # no teardown of ufbx's wrappers (see the module docstring)
