"""Zoo export: OBJ round trip, BVH Euler maths, BVH re-read by a small parser and by Blender (bpy)."""
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import trimesh

from mimicbench.datagen.zoo.dataset import build_zoo
from mimicbench.datagen.zoo.export_bvh import bvh_name, euler_zxy_to_matrix, matrix_to_euler_zxy
from mimicbench.geometry.quaternion import quat_normalize, quat_to_matrix
from mimicbench.schemas.shards import read_records


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("zoo_export")
    build_zoo(out, 7, seed=2, clips_per_character=3, export=("obj", "bvh"), progress=False)
    chars = {c.character_id: c for c in read_records(out, "characters")}
    motions = {m.motion_id: m for m in read_records(out, "motions")}
    return out, chars, motions


def test_euler_zxy_round_trip():
    q = quat_normalize(np.random.default_rng(0).normal(size=(200, 4)))
    m = quat_to_matrix(q)
    assert np.allclose(euler_zxy_to_matrix(matrix_to_euler_zxy(m)), m, atol=1e-9)


def test_obj_files_hold_the_rest_mesh(exported):
    out, chars, _ = exported
    for cid, c in chars.items():
        m = trimesh.load(out / "export" / f"{cid.split('/')[1]}.obj", process=False, force="mesh")
        assert m.faces.shape == c.faces.shape
        assert np.abs(np.asarray(m.vertices) - c.vertices).max() < 1e-5


def parse_bvh(path):
    """A minimal BVH reader: names, parents, offsets, channel orders and frames (for the test only)."""
    tokens = open(path).read().split()
    names, parents, offsets, stack, i = [], [], [], [], 0
    while tokens[i] != "MOTION":
        t = tokens[i]
        if t in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            i += 2
        elif t == "End":
            names.append(None)
            parents.append(stack[-1])
            i += 2
        elif t == "{":
            stack.append(len(names) - 1)
            i += 1
        elif t == "}":
            stack.pop()
            i += 1
        elif t == "OFFSET":
            offsets.append([float(x) for x in tokens[i + 1:i + 4]])
            i += 4
        elif t == "CHANNELS":
            i += 2 + int(tokens[i + 1])
        else:
            i += 1
    nf = int(tokens[i + 2])
    values = np.array(tokens[i + 6:], float).reshape(nf, -1)
    return names, np.array(parents), np.array(offsets), values


def bvh_positions(names, parents, offsets, frame):
    """World joint positions of one BVH frame (ZXY channels), end sites dropped."""
    joints = [k for k, n in enumerate(names) if n is not None]
    rot = {}
    pos = {}
    col = 3
    for k in range(len(names)):
        p = parents[k]
        if names[k] is None:
            continue
        local = euler_zxy_to_matrix(np.radians(frame[col:col + 3]))
        col += 3
        if p < 0:
            rot[k], pos[k] = local, frame[:3]
        else:
            rot[k] = rot[p] @ local
            pos[k] = pos[p] + rot[p] @ offsets[k]
    return [n for n in names if n is not None], np.array([pos[k] for k in joints])


def test_bvh_reparsed_gives_the_clip_joint_positions(exported):
    out, chars, motions = exported
    for mid, m in motions.items():
        cid, clip = mid.rsplit("/", 1)
        c = chars[cid]
        names, parents, offsets, values = parse_bvh(out / "export" / cid.split("/")[1] / f"{clip}.bvh")
        assert values.shape[0] == m.num_frames
        got_names, _ = bvh_positions(names, parents, offsets, values[0])
        assert sorted(got_names) == sorted(bvh_name(n) for n in c.bone_names)  # BVH order is depth first
        order = [got_names.index(bvh_name(n)) for n in c.bone_names]
        for f in (0, m.num_frames // 2, m.num_frames - 1):
            _, pos = bvh_positions(names, parents, offsets, values[f])
            assert np.abs(pos[order] - m.transforms[f, :, 4:]).max() < 1e-4, (mid, f)


BLENDER_READ = textwrap.dedent("""
    import json, sys
    import bpy
    jobs = json.loads(sys.argv[1])
    out = []
    for path, frames in jobs:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.import_anim.bvh(filepath=path, axis_forward="-Z", axis_up="Y", global_scale=1.0, frame_start=1,
                                use_fps_scale=False, rotate_mode="NATIVE")
        arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
        mw = arm.matrix_world
        res = {"names": [b.name for b in arm.data.bones],
               "rest": [list(mw @ b.head_local) for b in arm.data.bones], "frames": {}}
        for f in frames:
            bpy.context.scene.frame_set(1 + f)
            res["frames"][str(f)] = [list(mw @ arm.pose.bones[b.name].head) for b in arm.data.bones]
        out.append(res)
    print("JSON" + json.dumps(out))
""")


@pytest.mark.blender
def test_bvh_reimports_in_blender_with_the_same_joints(exported):
    """Blender's BVH importer (forward -Z, up Y) in a child process; Blender (x, y, z) -> ours (x, z, -y)."""
    out, chars, motions = exported
    jobs, expect = [], []
    for cid, c in sorted(chars.items()):  # one clip of every category
        m = motions[f"{cid}/random_poses"]
        path = out / "export" / cid.split("/")[1] / "random_poses.bvh"
        jobs.append([str(path), [0, 29]])
        expect.append((c, m))
    r = subprocess.run([sys.executable, "-c", BLENDER_READ, json.dumps(jobs)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    results = json.loads(next(line for line in r.stdout.splitlines() if line.startswith("JSON"))[4:])
    for (c, m), res in zip(expect, results):
        order = [res["names"].index(bvh_name(n)) for n in c.bone_names]

        def ours(points):
            p = np.asarray(points)[order]
            return np.stack([p[:, 0], p[:, 2], -p[:, 1]], 1)

        assert np.abs(ours(res["rest"]) - c.keypoints).max() < 1e-4, c.character_id
        assert np.abs(ours(res["frames"]["29"]) - m.transforms[29, :, 4:]).max() < 1e-4, c.character_id
        assert np.abs(m.transforms[29, :, 4:] - m.transforms[0, :, 4:]).max() > 1e-2  # the frame is posed
