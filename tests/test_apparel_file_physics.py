"""The apparel stage's physics from a character's own rigid bodies and joints
(datagen/apparel/file_physics.py): hand-built toys checked against hand-computed outcomes, and
Gene.pmx with Gene_stand.vmd through ``datagen ingest`` and ``datagen apparel``."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.apparel.file_physics import FileWorld
from mimicbench.datagen.apparel.file_plan import collision_filter, plan_scene
from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

PIVOT = np.array([0.0, 1.0, 0.0])
ARM = 0.5  # metres from the pivot to the pendulum bob
FREE = (np.ones(3), -np.ones(3))  # lower above upper: a free axis (Bullet's convention)


def _body(i, shape, size, pos, mode, group=0, mask=0xFFFF, bone=0, mass=1.0, damping=0.5):
    return RigidBodyRecord("toy", i, f"b{i}", "", bone, shape, np.float32(size), np.float32(pos),
                           np.float32([1, 0, 0, 0]), mass, damping, damping, 0.0, 0.5, group, mask, mode)


def _joint(a, b, rot_lo, rot_hi, spring=0.0):
    z = np.zeros(3, np.float32)
    return JointRecord("toy", 0, "j", "", "spring_6dof", a, b, np.float32(PIVOT), np.float32([1, 0, 0, 0]), z, z,
                       np.float32(rot_lo), np.float32(rot_hi), z, np.float32([spring] * 3))


def _pendulum(joint, extra=(), bob_mask=0xFFFF, damping=0.5):
    """Body 0: a small static sphere at the pivot (group 3); body 1: a dynamic sphere bob ARM
    metres along +X from it (group 1), hanging on ``joint``; ``extra`` static bodies after."""
    bodies = [_body(0, "sphere", [0.02, 0, 0], PIVOT, "static", group=3),
              _body(1, "sphere", [0.05, 0, 0], PIVOT + [ARM, 0, 0], "dynamic", group=1,
                    mask=bob_mask & ~(1 << 3), bone=1, damping=damping)]
    return bodies + list(extra), [joint]


def _run(bodies, joints, seconds, pose_of=None, gravity=9.8, contact_frequency=0.0):
    """Bob centre (3,) after ``seconds`` at 240 Hz; bones: 0 at the pivot, 1 (the bob's) at the bob."""
    keypoints = np.array([PIVOT, PIVOT + [ARM, 0, 0]])
    rest = rest_transforms(keypoints).astype(np.float64)
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0]), 1 / 240, 30, 0.08, gravity=gravity,
                   contact_frequency=contact_frequency) as world:
        for i in range(int(seconds * 240)):
            world.set_body_pose(rest if pose_of is None else pose_of(i / 240, rest))
            world.step()
        positions, _, _ = world.body_poses()
    return positions[1]


def _angle_about_z(p):
    d = p - PIVOT
    return float(np.arctan2(d[1], d[0]))


def test_collision_filter_is_the_group_bit_and_the_stored_mask():
    assert collision_filter(0, 0xFFFF) == (1, 0xFFFF)
    assert collision_filter(4, 0xFF8E) == (16, 0xFF8E)  # Gene's back hair
    assert collision_filter(15, 0x10000) == (1 << 15, 0)
    with pytest.raises(ValueError, match="0..15"):
        collision_filter(16, 0)


def _collides(g1, m1, g2, m2):
    """MMD/Bullet rule, written independently: each body's group bit in the other's mask."""
    return bool(m2 >> g1 & 1) and bool(m1 >> g2 & 1)


@pytest.mark.parametrize("bob_mask, shelf_mask", [(0xFFFF, 0xFFFF), (0xFFFF & ~(1 << 2), 0xFFFF),
                                                  (0xFFFF, 0xFFFF & ~(1 << 1)), (0x0000, 0xFFFF)])
def test_the_mask_decides_whether_the_bob_lands_on_the_shelf(bob_mask, shelf_mask):
    # the bob swings down from horizontal through a static shelf (group 2) across its arc
    shelf = _body(2, "box", [0.1, 0.02, 0.2], [0.25, 0.55, 0.0], "static", group=2, mask=shelf_mask)
    bodies, joints = _pendulum(_joint(0, 1, *FREE), [shelf], bob_mask=bob_mask, damping=0.9)
    bob = _run(bodies, joints, 3.0)
    if _collides(1, bob_mask & ~(1 << 3), 2, shelf_mask):
        assert bob[0] > 0.2 and bob[1] > 0.55  # stopped on the shelf
    else:
        assert abs(bob[0]) < 0.05 and abs(bob[1] - (PIVOT[1] - ARM)) < 0.01  # hangs below the pivot


@pytest.mark.parametrize("frequency", [0.0, 30.0, 45.0])
def test_a_contact_spring_lets_a_resting_bob_sink_g_over_w_squared(frequency):
    # the bob, released horizontal, rests on a static shelf whose top touches its bottom; the
    # contact carries its whole weight (the contact point is under its centre, at the same lever
    # arm), so a spring of stiffness m w^2 is pressed g / w^2 deep (10.9 mm at 30 rad/s, 4.8 at
    # 45); Bullet's rigid contact lets it in by its slop only
    top = PIVOT[1] - 0.05
    shelf = _body(2, "box", [0.1, 0.02, 0.2], [ARM, top - 0.02, 0.0], "static", group=2)
    bodies, joints = _pendulum(_joint(0, 1, *FREE), [shelf], damping=0.9)
    bob = _run(bodies, joints, 3.0, contact_frequency=frequency)
    depth = top - (bob[1] - 0.05)
    if frequency == 0:
        assert depth < 0.002
    else:
        assert depth == pytest.approx(9.8 / frequency ** 2, rel=0.05)  # measured 10.6 and 4.72 mm
    assert np.linalg.norm(bob - PIVOT) == pytest.approx(ARM, abs=1e-3)


@pytest.mark.parametrize("lo, hi, reverse, expected", [(-0.3, 0.1, False, -0.3), (-0.1, 0.6, False, -0.1),
                                                       (-0.1, 0.3, True, -0.3)])
def test_rotation_limits_hold_under_gravity(lo, hi, reverse, expected):
    # gravity turns the horizontal bob about -Z; it stops at the range's lower bound about Z
    # (a reversed joint, bob as body A, limits the pivot against the bob: the range negates)
    joint = _joint(1, 0, [0, 0, lo], [0, 0, hi]) if reverse else _joint(0, 1, [0, 0, lo], [0, 0, hi])
    bodies, joints = _pendulum(joint, damping=0.9)
    bob = _run(bodies, joints, 2.0)
    assert _angle_about_z(bob) == pytest.approx(expected, abs=0.02)
    assert np.linalg.norm(bob - PIVOT) == pytest.approx(ARM, abs=1e-3)  # translation locked


@pytest.mark.parametrize("spring", [0.0, 2000.0])
def test_a_spring_returns_to_rest(spring):
    # no gravity: the pivot's bone turns 0.5 rad about Z at once and holds; a free bob keeps its
    # place (it lags 0.5 rad behind the turned frame), a sprung one follows back to rest
    def turned(t, rest):
        pose = rest.copy()
        if t > 0.1:
            pose[0, :4] = [np.cos(0.25), 0, 0, np.sin(0.25)]
        return pose

    bodies, joints = _pendulum(_joint(0, 1, *FREE, spring=spring), damping=0.5)
    bob = _run(bodies, joints, 3.0, turned, gravity=0.0)
    lag = 0.5 - _angle_about_z(bob)
    if spring:
        assert abs(lag) < 0.05
    else:
        assert lag > 0.3


def test_gene_scene_plan(assets_dir):
    from mimicbench.datagen.mmd.physics import physics_records
    from mimicbench.datagen.mmd.pmx import read_pmx
    from mimicbench.datagen.mmd.records import topological_order

    model = read_pmx(assets_dir / "mmd" / "Gene.pmx")
    order = topological_order(np.array([b.parent for b in model.bones]))
    new_index = np.empty(len(order), np.int64)
    new_index[order] = np.arange(len(order))
    bodies, joints = physics_records(model, "gene", new_index)
    plan = plan_scene(bodies, joints)
    links = sorted(b for c in plan.chains for b in c.links)
    # LICENSES.md: 9 physics + 53 physics-and-bone bodies, every one hangs from a bone-following one
    assert links == [i for i, b in enumerate(bodies) if b.mode != "static"] and len(links) == 62
    assert plan.unanchored == [] and all(bodies[c.anchor].mode == "static" for c in plan.chains)
    # by the file's own numbers: the 8 cloak ring joints ("_J", free along y only) close loops as
    # point-to-point constraints; left out are the 13 reverse ("-") joints, which double a tree
    # joint's pair, and the 9 weight joints ("補"), free on every axis
    assert sorted(joints[j].name for j in plan.loops) == sorted(j.name for j in joints if j.name.endswith("_J"))
    assert len(plan.loops) == 8
    names = {joints[j].name: why for j, why in plan.dropped.items()}
    assert len(names) == 22
    assert {n for n, why in names.items() if why == "its bodies are joined already"} == \
        {n for n in names if n.endswith("-")} and sum(n.endswith("-") for n in names) == 13
    assert sum(n.endswith("補") for n in names) == 9


@pytest.mark.slow
def test_gene_stand_through_ingest_and_apparel(assets_dir, tmp_path):
    from mimicbench.cli import main
    from mimicbench.schemas.shards import read_records

    assert main(["datagen", "ingest", str(assets_dir / "mmd" / "Gene.pmx"), "--out", str(tmp_path / "gene"),
                 "--quiet"]) == 0
    assert main(["datagen", "apparel", str(tmp_path / "gene"), str(tmp_path / "sim"), "--quiet"]) == 0
    c = read_records(tmp_path / "sim", "characters")[0]
    motions = {m.name: m for m in read_records(tmp_path / "sim", "motions")}
    stand, sim = motions["stand"], motions["stand@sim"]
    q = c.meta["apparel"]["clips"]["stand"]
    assert q["physics"] == "file" and q["links"] == 62 and q["gravity"] == pytest.approx(9.8)
    assert np.isfinite(q["new_inside_pct"]) and q["secondary_motion_pct"] > 0.1
    body = ~c.apparel_bone_mask
    np.testing.assert_array_equal(sim.transforms[:, body], stand.transforms[:, body])
    moved = np.linalg.norm(sim.transforms[:, :, 4:] - stand.transforms[:, :, 4:], axis=-1).max(axis=0)
    by_kind: dict[str, float] = {}
    for chain in c.meta["mmd"]["apparel_chains"]:
        by_kind[chain["kind"]] = max(by_kind.get(chain["kind"], 0.0), float(moved[chain["bones"]].max()))
    # the hair, the skirt (すそ) and the coat (クローク, kind other) all swing in the standing clip
    assert by_kind["hair"] > 0.005 and by_kind["skirt"] > 0.0005 and by_kind["other"] > 0.005, by_kind
    # no explosion: the apparel mesh stays within 5% of the height of the clip's, and smooth
    assert q["secondary_motion_max_pct"] < 5.0 and q["max_accel"] < 50.0
    assert len(read_records(tmp_path / "sim", "rigid_bodies")) == 87


def _held_out_names(names: list[str]) -> list[str]:
    """Another rig's naming: English bone names without the zoo's prefix, and chains named
    Flap/Strand/Drape (no apparel word) instead of Skirt/Hair/Cape."""
    chain = {"Skirt": "Flap", "Hair": "Strand", "Cape": "Drape"}
    out = []
    for n in names:
        n = n.split(":", 1)[-1]
        parts = n.split("_")
        out.append(f"{chain[parts[0]]}{parts[1]}.{int(parts[2])}" if parts[0] in chain else n)
    return out


@pytest.mark.slow
def test_held_out_pmx_with_other_names_gets_its_apparel_from_its_bodies(tmp_path):
    import dataclasses

    from mimicbench.datagen.mmd.chain_physics import chain_physics
    from mimicbench.datagen.mmd.pmx_writer import write_pmx
    from mimicbench.datagen.zoo.build import build_character
    from mimicbench.datagen.zoo.plan import plan_zoo
    from mimicbench.cli import main
    from mimicbench.schemas.shards import read_records
    from tests.mmd_fixtures import vmd_bytes

    spec = [s for s in plan_zoo(24, seed=0) if s.category == "apparel"][0]
    zoo = build_character(spec, "train", 0, 10).record
    c = dataclasses.replace(zoo, bone_names=_held_out_names(zoo.bone_names), bone_roles=None)
    bodies, joints = chain_physics(c)
    write_pmx(tmp_path / "rig.pmx", c, bodies, joints)
    # a quarter turn of the hips in 6 frames, then held: the apparel lags and swings back
    turn = [("Hips", f, (0, 0, 0), (0, np.sin(a / 2), 0, np.cos(a / 2)), {}) for f, a in ((0, 0), (6, np.pi / 2),
                                                                                           (20, np.pi / 2))]
    (tmp_path / "rig_turn.vmd").write_bytes(vmd_bytes(turn))
    assert main(["datagen", "ingest", str(tmp_path / "rig.pmx"), "--out", str(tmp_path / "ds"), "--quiet"]) == 0
    (rig,) = read_records(tmp_path / "ds", "characters")
    assert rig.bone_names == c.bone_names and "Strand03.2" in rig.bone_names
    np.testing.assert_array_equal(rig.apparel_bone_mask, zoo.apparel_bone_mask)  # from the dynamic bodies alone
    assert main(["datagen", "apparel", str(tmp_path / "ds"), str(tmp_path / "sim"), "--relax-frames", "10", "--quiet"]) == 0
    motions = {m.name: m for m in read_records(tmp_path / "sim", "motions")}
    kin, sim = motions["turn"], motions["turn@sim"]
    q = read_records(tmp_path / "sim", "characters")[0].meta["apparel"]["clips"]["turn"]
    assert q["physics"] == "file" and q["links"] == int(zoo.apparel_bone_mask.sum()) and q["dropped_joints"] == 0
    body = ~rig.apparel_bone_mask
    np.testing.assert_array_equal(sim.transforms[:, body], kin.transforms[:, body])
    assert q["secondary_motion_max_pct"] > 0.5 and q["secondary_motion_max_pct"] < 20.0


@pytest.mark.parametrize("free_axes, held", [(0, True), (1, True), (2, False)])
def test_a_loop_joint_ties_a_free_bob_to_a_held_one(free_axes, held):
    # bob 1 hangs on a locked (fixed) joint, horizontal; bob 2, 0.2 m beside it, on a free joint;
    # a third joint ties bob 2 to bob 1: point-to-point (bob 2 stays up) unless two or more of
    # its translation axes are free (dropped: bob 2 swings down under the pivot)
    side = np.array([0.0, 0.0, 0.2])
    bodies = [_body(0, "sphere", [0.02, 0, 0], PIVOT, "static", group=3),
              _body(1, "sphere", [0.05, 0, 0], PIVOT + [ARM, 0, 0], "dynamic", group=1, mask=0, bone=1),
              _body(2, "sphere", [0.05, 0, 0], PIVOT + [ARM, 0, 0] + side, "dynamic", group=1, mask=0, bone=1)]
    z = np.zeros(3)
    fixed, free = _joint(0, 1, z, z), _joint(0, 2, *FREE)
    free = JointRecord(**{**free.__dict__, "position": np.float32(PIVOT + side)})
    lo, hi = np.zeros(3, np.float32), np.zeros(3, np.float32)
    lo[:free_axes], hi[:free_axes] = 1.0, -1.0  # lower above upper: free
    tie = JointRecord("toy", 2, "tie", "", "spring_6dof", 1, 2, np.float32(PIVOT + [ARM, 0, 0] + side),
                      np.float32([1, 0, 0, 0]), lo, hi, np.float32(z), np.float32(z), np.float32(z), np.float32(z))
    plan = plan_scene(bodies, [fixed, free, tie])
    assert plan.loops == ([2] if held else []) and (2 in plan.dropped) != held
    keypoints = np.array([PIVOT, PIVOT + [ARM, 0, 0]])
    rest = rest_transforms(keypoints).astype(np.float64)
    with FileWorld(bodies, [fixed, free, tie], keypoints, np.array([-1, 0]), 1 / 240, 30, 0.08) as world:
        for _ in range(480):
            world.set_body_pose(rest)
            world.step()
        positions, _, _ = world.body_poses()
    assert positions[1][1] == pytest.approx(PIVOT[1], abs=0.01)  # the fixed bob holds
    if held:
        assert positions[2][1] == pytest.approx(PIVOT[1], abs=0.03)
    else:
        assert positions[2][1] < PIVOT[1] - 0.4


def test_the_file_world_runs_through_the_one_clip_loop():
    # the pendulum released from horizontal, as a 30 fps clip of 20 frames: the static bone keeps
    # the clip's rows, the bob's bone head stays ARM from the pivot and swings down; a speed bound below
    # the bob's speed (it reaches about sqrt(2 g ARM) = 3.1 m/s at the bottom) is an explosion
    from mimicbench.datagen.apparel.simulate import SimulationExploded, simulate_clip

    bodies, joints = _pendulum(_joint(0, 1, *FREE))
    keypoints = np.array([PIVOT, PIVOT + [ARM, 0, 0]])
    clip = np.repeat(rest_transforms(keypoints)[None], 20, axis=0).astype(np.float32)
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0]), 1 / 240, 30, 0.08, apparel=np.array([False, True]),
                   max_speed=25.0) as world:
        out = simulate_clip(world, clip, 8, 0).transforms
    np.testing.assert_array_equal(out[:, 0], clip[:, 0])
    arm = np.linalg.norm(out[:, 1, 4:] - PIVOT, axis=1)
    np.testing.assert_allclose(arm, ARM, atol=2e-3)
    assert out[0, 1, 5] > PIVOT[1] - 0.1 and out[:, 1, 5].min() < PIVOT[1] - 0.45  # swung through the bottom
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0]), 1 / 240, 30, 0.08, max_speed=1.0) as world:
        with pytest.raises(SimulationExploded, match=r"a link reached .* m/s at frame \d+ \(bound 1 m/s\)"):
            simulate_clip(world, clip, 8, 0, max_resettles=0)  # no re-settles: the first escape fails the clip


def test_a_struck_file_chain_is_resettled_at_rest_on_its_anchor():
    # the pendulum released from horizontal while bone 0 (the pivot's) turns about Y at 0.6 rad/s;
    # after frame 12 the bob is struck to 40 m/s (bound 25): it is put back at rest, horizontal on
    # the turned pivot (its bone at the pivot plus the turned rest arm, turned as bone 0 is), and
    # swings down again; the frames before are those of the clip simulated without the strike
    from mimicbench.datagen.apparel.simulate import SimulationExploded, simulate_clip

    bodies, joints = _pendulum(_joint(0, 1, *FREE))
    keypoints = np.array([PIVOT, PIVOT + [ARM, 0, 0]])
    clip = np.repeat(rest_transforms(keypoints)[None], 30, axis=0).astype(np.float64)
    angles = np.arange(30) * 0.02
    clip[:, :, :4] = np.stack([np.cos(angles / 2), 0 * angles, np.sin(angles / 2), 0 * angles], axis=1)[:, None]
    clip[:, 1, 4:] = PIVOT + ARM * np.stack([np.cos(angles), 0 * angles, -np.sin(angles)], axis=1)

    class Struck:  # the world, its bob's multibody given base velocity 40 m/s along X after frame ``n``
        def __init__(self, world, n):
            self.world, self.n, self.seen, self.counts = world, n, 0, []

        def __getattr__(self, name):
            return getattr(self.world, name)

        def follow(self, poses, per_frame):
            for f in self.world.follow(poses, per_frame):
                if self.seen == self.n:
                    mb = self.world.chains[0][2]
                    self.world.pb.resetBaseVelocity(mb, [40.0, 0.0, 0.0], physicsClientId=self.world.client)
                self.seen += 1
                yield f

        def resettle(self, pose):
            self.counts.append(self.world.resettle(pose))
            return self.counts[-1]

    def run(n, max_resettles=5):
        with FileWorld(bodies, joints, keypoints, np.array([-1, 0]), 1 / 240, 30, 0.08,
                       apparel=np.array([False, True])) as world:
            struck = Struck(world, n)
            return simulate_clip(struck, clip, 8, 0, max_resettles), struck.counts

    n = 12
    (plain, _), (struck, counts) = run(-1), run(n)
    assert plain.resettled_frames == [] and struck.resettled_frames == [n] and counts == [1]
    assert struck.transforms[:n].tobytes() == plain.transforms[:n].tobytes()
    a = angles[n]
    np.testing.assert_allclose(struck.transforms[n, 1, 4:], PIVOT + ARM * np.array([np.cos(a), 0.0, -np.sin(a)]),
                               atol=1e-5)
    q = struck.transforms[n, 1, :4] * np.sign(struck.transforms[n, 1, 0])
    np.testing.assert_allclose(q, [np.cos(a / 2), 0.0, np.sin(a / 2), 0.0], atol=1e-5)
    assert plain.transforms[n, 1, 5] < PIVOT[1] - 0.1  # unstruck, the bob had swung down
    assert struck.transforms[n + 5, 1, 5] < PIVOT[1] - 0.02  # struck, it swings down again from rest
    with pytest.raises(SimulationExploded, match=r"^a link reached \d+\.\d m/s at frame 12 \(bound 25 m/s\)$"):
        run(n, 0)


@pytest.mark.slow
def test_gene_keeps_its_file_physics_through_resample_and_retarget(assets_dir, tmp_path):
    """A user's path: an MMD model ingested, resampled, given another character's clip by
    ``datagen retarget`` and simulated. The file's 87 bodies and 92 joints travel with the
    character through both stages (without them ``datagen apparel`` fell back to the zoo's chain
    defaults on Gene's apparel bones, and a dance exploded there), and the retargeted clip is
    simulated with the file's physics."""
    from mimicbench.datagen.zoo.build import build_character
    from mimicbench.datagen.zoo.plan import plan_zoo
    from mimicbench.cli import main
    from mimicbench.schemas.shards import read_records, write_records

    spec = [s for s in plan_zoo(12, seed=0) if s.category == "humanoid"][0]
    walker = build_character(spec, "train", 1, 24)
    write_records(tmp_path / "walk", "characters", [walker.record], "train")
    write_records(tmp_path / "walk", "motions", walker.motions[:1], "train")
    assert main(["datagen", "ingest", str(assets_dir / "mmd" / "Gene.pmx"), "--out", str(tmp_path / "gene"),
                 "--quiet"]) == 0
    assert main(["datagen", "resample", str(tmp_path / "gene"), str(tmp_path / "g5k"), "--quiet"]) == 0
    assert main(["datagen", "retarget", str(tmp_path / "walk"), str(tmp_path / "g5k"), str(tmp_path / "moved"),
                 "--quiet"]) == 0
    source = {t: read_records(tmp_path / "gene", t) for t in ("rigid_bodies", "joints")}
    for folder in ("g5k", "moved"):
        for table, rows in source.items():
            copied = read_records(tmp_path / folder, table)
            assert [(r.character_id, r.name, r.mode if table == "rigid_bodies" else r.kind) for r in copied] == \
                [(r.character_id, r.name, r.mode if table == "rigid_bodies" else r.kind) for r in rows], (folder, table)
    assert len(source["rigid_bodies"]) == 87 and len(source["joints"]) == 92
    assert main(["datagen", "apparel", str(tmp_path / "moved"), str(tmp_path / "sim"), "--relax-frames", "5",
                 "--quiet"]) == 0
    (c,) = read_records(tmp_path / "sim", "characters")
    ((clip, q),) = c.meta["apparel"]["clips"].items()
    assert clip == f"{walker.record.character_id}/{walker.motions[0].name}"
    assert q["physics"] == "file" and q["links"] == 62 and q["resettles"] == 0
