"""The apparel stage on the zoo's apparel characters, checked with independent tools.

LBS is written out here with dense weights, and penetration is measured with libigl's generalized
winding number on the posed body surface (not the stage's own convex pieces).
"""
from __future__ import annotations

import igl
import numpy as np
import pytest

from mimicbench.datagen.apparel.stage import simulate_dataset
from mimicbench.schemas.shards import read_records


def _quat_matrices(q):
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def _pose(c, transforms):
    """(F, N, 3) v_i = sum_k W_ik (R(q_k) (v_i - c_k) + t_k), by hand with dense weights."""
    n, k = len(c.vertices), len(c.parents)
    dense = np.zeros((n, k))
    np.add.at(dense, (np.repeat(np.arange(n), 8), c.weight_indices.ravel()), c.weight_values.ravel())
    rot = _quat_matrices(transforms[..., :4].astype(np.float64))  # (F, K, 3, 3)
    local = c.vertices[None, :, None, :].astype(np.float64) - c.keypoints[None, None].astype(np.float64)  # (1, N, K, 3)
    per_bone = np.einsum("fkab,fnkb->fnka", rot, np.broadcast_to(local, (len(transforms), n, k, 3)))
    per_bone = per_bone + transforms[:, None, :, 4:].astype(np.float64)
    return np.einsum("nk,fnka->fna", dense, per_bone), dense


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_zoo_apparel_simulated_moves_apparel_only_and_stays_outside_the_body(tmp_path, seed):
    from mimicbench.datagen.zoo.dataset import build_zoo

    zoo = tmp_path / "zoo"
    build_zoo(zoo, 3, seed=seed, categories=["apparel"], clips_per_character=1, progress=False)
    out = tmp_path / "sim"
    s = simulate_dataset(zoo, out, relax=20, progress=False)
    assert s["failed"] == 0 and s["simulated"] == 3
    chars = {c.character_id: c for c in read_records(out, "characters")}
    motions = {m.motion_id: m for m in read_records(out, "motions")}
    kinds, per_clip, worst = set(), {}, 0.0
    for m in [m for m in motions.values() if m.name.endswith("@sim")]:
        c = chars[m.character_id]
        kinds |= {r.split("/")[1] for r in c.bone_roles if r.startswith("apparel/")}
        kin = motions[m.motion_id[: -len("@sim")]]
        sim_v, dense = _pose(c, m.transforms)
        kin_v, _ = _pose(c, kin.transforms)
        apparel = c.apparel_vertex_mask
        untouched = dense[:, c.apparel_bone_mask].sum(axis=1) == 0  # body vertices with no apparel weight
        assert untouched.sum() > 0.3 * len(untouched)
        # body vertices: same as the kinematic clip; apparel vertices: moved (secondary motion)
        assert np.abs(sim_v[:, untouched] - kin_v[:, untouched]).max() < 1e-5
        moved = np.linalg.norm(sim_v[:, apparel] - kin_v[:, apparel], axis=-1)
        assert moved.mean(axis=1).max() > 0.01 * c.height, m.motion_id
        # penetration: apparel vertices inside the posed body surface (winding number > 1/2) that were
        # outside it at rest (the zoo's hair roots sit in the scalp at rest)
        faces = c.faces[~apparel[c.faces].any(axis=1)]
        rest_in = igl.winding_number(c.vertices.astype(np.float64), faces, c.vertices[apparel].astype(np.float64)) > 0.5
        clip_inside = []
        for f in range(0, len(sim_v), 4):
            inside = igl.winding_number(sim_v[f], faces, sim_v[f][apparel]) > 0.5
            clip_inside.append(float(np.mean(inside & ~rest_in)))
            worst = max(worst, clip_inside[-1])
        per_clip[m.motion_id] = float(np.mean(clip_inside))
    # the issue's bound: below 1% in every clip (every 4th frame; the worst clip, seed 0's
    # apparel-0000 walk, is at 0.50%); no frame above 2%
    assert max(per_clip.values()) < 0.01, per_clip
    assert worst < 0.02, worst
    assert {"skirt", "hair", "cape"} <= kinds  # every variant of the zoo's apparel template took part


@pytest.mark.slow
def test_a_clip_gives_the_same_bytes_whether_its_world_was_reused_or_new(tmp_path):
    # the stage keeps one world per character across its clips (reset between them); a clip's
    # simulation must not depend on the clips simulated before it in that world: simulated alone
    # (a new world) it gives the same bytes as second in line (a reused world)
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import write_records

    zoo = tmp_path / "zoo"
    build_zoo(zoo, 1, seed=0, categories=["apparel"], clips_per_character=2, frames_per_clip=24, progress=False)
    both = simulate_dataset(zoo, tmp_path / "both", relax=10, progress=False)
    assert both["simulated"] == 2
    chars = list(read_records(zoo, "characters"))
    clips = list(read_records(zoo, "motions"))
    alone = tmp_path / "alone_in"
    write_records(alone, "characters", chars, split=chars[0].split)
    write_records(alone, "motions", clips[1:], split=clips[1].split)
    simulate_dataset(alone, tmp_path / "alone", relax=10, progress=False)
    reused = {m.motion_id: m for m in read_records(tmp_path / "both", "motions")}
    new = {m.motion_id: m for m in read_records(tmp_path / "alone", "motions")}
    sim_id = clips[1].motion_id + "@sim"
    assert sim_id in new and sim_id in reused
    assert new[sim_id].transforms.tobytes() == reused[sim_id].transforms.tobytes()


@pytest.mark.slow
def test_an_idle_clip_that_exploded_at_simulation_version_8_simulates(tmp_path):
    # issue 33: zoo seed 505's apparel-0003 idle clip exploded at version 8 (a link at 29.0 m/s at
    # frame 12, bound 25 m/s; its hair twisted by contacts and put back into the body every step).
    # It must simulate, its apparel moving (secondary motion) yet staying out of the body, and its
    # links stay far below the bound: no vertex faster than the bound's tenth on average over a frame
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import write_records

    zoo = tmp_path / "zoo"
    build_zoo(zoo, 4, seed=505, categories=["apparel"], clips_per_character=2, progress=False)
    c = next(c for c in read_records(zoo, "characters") if c.character_id == "zoo/apparel-0003")
    idle = [m for m in read_records(zoo, "motions") if m.character_id == c.character_id and m.name == "idle"]
    one = tmp_path / "idle"
    write_records(one, "characters", [c], split=c.split)
    write_records(one, "motions", idle, split=c.split)
    s = simulate_dataset(one, tmp_path / "sim", progress=False)  # 30 relaxation frames, as the stage's default
    assert s["failed"] == 0 and s["simulated"] == 1
    sim = next(m for m in read_records(tmp_path / "sim", "motions") if m.name == "idle@sim")
    posed, _ = _pose(c, sim.transforms)
    apparel = posed[:, c.apparel_vertex_mask]
    speed = np.linalg.norm(np.diff(apparel, axis=0), axis=-1) * sim.fps  # (F - 1, A) m/s
    assert speed.mean(axis=1).max() < 2.5, speed.mean(axis=1).max()
    kin, _ = _pose(c, idle[0].transforms)
    moved = np.linalg.norm(apparel - kin[:, c.apparel_vertex_mask], axis=-1).mean(axis=1)
    assert moved.max() > 0.002 * c.height  # the apparel lags and sways, it is not frozen
