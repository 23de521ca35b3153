"""Apparel physics on a hand-built pendulum character (tests/apparel_toys.py): rest, lag, limits, URDF."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.spatial import Delaunay

from mimicbench.datagen.apparel.params import ApparelParams, load_params, params_from_json
from mimicbench.datagen.apparel.selection import apparel_vertex_mask, bone_kind, bones_matching
from mimicbench.datagen.apparel.setup import character_physics, simulate_motion
from mimicbench.datagen.apparel.simulate import SimulationExploded
from mimicbench.datagen.apparel.springs import chain_mass_matrix
from mimicbench.datagen.apparel.urdf import chain_urdf, hull_obj
from mimicbench.datagen.apparel.world import ApparelWorld
from mimicbench.schemas.errors import UserError
from tests.apparel_toys import LINK, LINKS, make_character, make_motion, quick_turn


def _hand_rotation(q):
    """3x3 matrix of a (w, x, y, z) quaternion, written out (not the project's helper)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _simulate(angles, params=None, relax=30):
    rec = make_character()
    params = params or ApparelParams()
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    motion = make_motion(rec, angles)
    sim, quality = simulate_motion(rec, physics, motion, params, 240.0, relax)
    return rec, motion, sim, quality


def test_chain_at_rest_under_gravity_stays_put():
    rec, motion, sim, quality = _simulate(np.zeros(60))
    # a vertical chain hanging from a still body: every bone stays at its rest head, unrotated
    np.testing.assert_allclose(sim.transforms[:, :, 4:], np.broadcast_to(rec.keypoints, sim.transforms[:, :, 4:].shape),
                               atol=1e-3)
    angles = 2 * np.degrees(np.arccos(np.clip(np.abs(sim.transforms[:, :, 0]), 0, 1)))
    assert angles.max() < 0.5
    assert quality["secondary_motion_max_pct"] < 0.1


def test_chain_on_a_quickly_turning_bone_lags_swings_back_and_settles():
    angles = quick_turn(120, 4)  # a quarter turn about Y in 4 frames (0.13 s), then held for 3.9 s
    rec, motion, sim, quality = _simulate(angles)
    tip_kin = motion.transforms[:, LINKS, 4:].astype(np.float64)
    tip_sim = sim.transforms[:, LINKS, 4:].astype(np.float64)
    # the kinematic tip, by hand: rest tip turned about the Y axis through the torso head (0, 1, 0)
    a = angles[-1]
    rest_tip = rec.keypoints[LINKS] - np.array([0, 1.0, 0])
    by_hand = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]) @ rest_tip + [0, 1.0, 0]
    np.testing.assert_allclose(tip_kin[-1], by_hand, atol=1e-6)
    lag = np.linalg.norm(tip_sim - tip_kin, axis=1)
    chain = LINKS * LINK
    assert lag.max() > 0.25 * chain  # stated bound: the tip trails by more than a quarter of the chain
    assert np.argmax(lag) < 20  # during or right after the turn
    # swings back toward the kinematic pose within a second of the peak, and settles there
    peak = int(np.argmax(lag))
    assert lag[peak + 30] < 0.5 * lag[peak]
    assert lag[-30:].max() < 0.1 * lag.max()
    assert np.abs(np.diff(tip_sim[-30:], axis=0)).max() < 0.002  # still: under 2 mm a frame
    assert quality["secondary_motion_max_pct"] > 5.0
    # body bone untouched, bit for bit
    np.testing.assert_array_equal(sim.transforms[:, 0], motion.transforms[:, 0])


def test_swing_limit_holds_a_horizontal_chain_under_gravity():
    # no motor: gravity bends every joint of a chain sticking out along +X until its 0.3 rad limit holds
    rec = make_character(horizontal=True)
    params = params_from_json({"kinds": {"skirt": {"swing_limit": 0.3, "twist_limit": 0.1, "strength": 0.0,
                                                   "stiffness": 0.0}}})
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    sim, _ = simulate_motion(rec, physics, make_motion(rec, np.zeros(60)), params, 240.0, 0)
    q = sim.transforms[-1, :, :4].astype(np.float64)
    # joint frame of every chain bone: +Z along the bone (+X), i.e. a quarter turn about +Y
    frame = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    for k in range(1, LINKS + 1):  # each joint's rotation in its own frame, by hand (Rodrigues' inverse)
        rel = frame.T @ _hand_rotation(q[k - 1]).T @ _hand_rotation(q[k]) @ frame
        angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
        axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]]) / (2 * np.sin(angle))
        swing_x, swing_y, twist = np.abs(axis * angle)
        assert swing_x < 0.3 + 0.07 and swing_y < 0.3 + 0.07 and twist < 0.1 + 0.07, (k, axis * angle)
        if k == 1:  # gravity bends the first joint down about the bone's X until the limit holds
            assert swing_x == pytest.approx(0.3, abs=0.07)
    tip = sim.transforms[-1, LINKS, 4:]
    assert tip[1] < 1.0 - 0.05  # the chain sags below its rest height


def _joint_rotvecs(q_parent, q_child, frame):
    """(F, 3) rotation vectors of a joint in its own frame, by hand: frame^T R_parent^T R_child frame."""
    out = []
    for a, b in zip(q_parent, q_child):
        rel = frame.T @ _hand_rotation(a).T @ _hand_rotation(b) @ frame
        angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
        axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
        out.append(axis / (2 * np.sin(angle)) * angle if angle > 1e-9 else np.zeros(3))
    return np.array(out)


@pytest.mark.parametrize("turn_frames", [4, 2])
def test_limits_hold_within_tolerance_on_a_fast_turn(turn_frames):
    # a quarter turn in 4 or 2 frames (11.8 or 23.6 rad/s) swings the hanging chain against a
    # 0.4 rad swing limit and twists it against a 0.15 rad twist limit; every joint's rotation
    # (measured by hand from the stored bone rotations) stays within 0.01 rad of its limits on every
    # frame; the first one, relative to the body bone, within 0.02 rad: the anchor's lag behind its
    # bone counts there too (twist 0.160 rad at simulation version 11, 0.167 at 12, whose springs
    # take the chain's mass matrix at its present, swung-up pose)
    rec = make_character()
    params = params_from_json({"kinds": {"skirt": {"swing_limit": 0.4, "twist_limit": 0.15}}})
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    sim, quality = simulate_motion(rec, physics, make_motion(rec, quick_turn(40, turn_frames)), params, 240.0, 10)
    q = sim.transforms[:, :, :4].astype(np.float64)
    frame = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # joint frame: a quarter turn about X, +Z down the bone
    swing, twist = 0.0, 0.0
    for k in range(1, LINKS + 1):
        r = _joint_rotvecs(q[:, k - 1], q[:, k], frame)  # (F, 3)
        slack = 0.02 if k == 1 else 0.01
        swing = max(swing, float(np.linalg.norm(r[:, :2], axis=1).max()) - slack + 0.01)
        twist = max(twist, float(np.abs(r[:, 2]).max()) - slack + 0.01)
    assert swing < 0.4 + 0.01 and twist < 0.15 + 0.01, (swing, twist)
    assert swing > 0.3  # the turn did swing the chain up to the limit
    assert quality["secondary_motion_max_pct"] > 5.0


def test_gravity_is_a_parameter():
    # a horizontal chain with neither motor nor stiffness: without gravity it stays level, with the
    # default 9.8 m/s^2 it sags, and more under 3 times that gravity
    assert ApparelParams().simulation.gravity == pytest.approx(9.8)
    tips = {}
    for g in (0.0, 9.8, 29.4):
        rec = make_character(horizontal=True)
        params = params_from_json({"simulation": {"gravity": g}, "kinds": {"skirt": {
            "swing_limit": 3.0, "twist_limit": 0.1, "strength": 0.0, "stiffness": 0.0}}})
        physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
        sim, _ = simulate_motion(rec, physics, make_motion(rec, np.zeros(6)), params, 240.0, 0)
        tips[g] = sim.transforms[:, LINKS, 5].astype(np.float64)  # tip height per frame
    np.testing.assert_allclose(tips[0.0], 1.0, atol=1e-3)
    # starting from rest, the early drop scales with g (drop ~ a t^2 / 2 with a proportional to g):
    # three times the gravity drops the tip about three times as far in the first frame
    drop = {g: 1.0 - tip for g, tip in tips.items()}
    assert drop[9.8][0] > 0.003 and drop[29.4][0] / drop[9.8][0] == pytest.approx(3.0, rel=0.15)
    assert np.all(np.diff(drop[9.8]) > 0)  # and keeps falling


def test_a_reset_world_simulates_a_clip_as_a_new_one_does():
    # one world per character is reused across its clips; after reset() a clip gives the same
    # bytes as in a new world, whatever was simulated before it (here a clip that hit the limits)
    rec = make_character()
    params = ApparelParams()
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    turn, sway = make_motion(rec, quick_turn(30, 2), "turn"), make_motion(rec, np.sin(np.arange(30) / 4.0), "sway")
    new = {m.name: simulate_motion(rec, physics, m, params, 240.0, 8)[0].transforms for m in (turn, sway)}
    with ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240) as world:
        for m in (turn, sway, turn):
            world.reset()
            again = simulate_motion(rec, physics, m, params, 240.0, 8, world)[0].transforms
            assert again.tobytes() == new[m.name].tobytes(), m.name


def test_a_world_on_a_reused_client_simulates_as_one_on_a_new_client(monkeypatch):
    # a closed world hands its pybullet client to the next world of the process, which empties it
    # (resetSimulation) instead of connecting anew; the bytes must be those of a world on a
    # client never used before, whatever the client held (here a world of another character)
    import dataclasses

    import pybullet

    import mimicbench.datagen.apparel.world as world_module
    from mimicbench.datagen.apparel.params import params_from_json

    rec = make_character()
    params = ApparelParams()
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    turn = make_motion(rec, quick_turn(30, 2), "turn")
    monkeypatch.setattr(world_module, "_IDLE_CLIENTS", [])
    monkeypatch.setattr(world_module, "MAX_IDLE_CLIENTS", 0)  # every world on a new client
    fresh = simulate_motion(rec, physics, turn, params, 240.0, 8)[0].transforms
    monkeypatch.setattr(world_module, "MAX_IDLE_CLIENTS", 1)
    # the other character's torso box sits where this one's chain hangs: left in the client, it
    # would strike the chain
    shift = np.array([0.25, -0.3, 0.0], np.float32)
    other_rec = dataclasses.replace(rec, character_id="toy/other", vertices=rec.vertices + shift,
                                    keypoints=rec.keypoints + shift)
    other = params_from_json({"kinds": {"skirt": {"swing_limit": 0.3, "strength": 0.0}}})
    other_physics = character_physics(other_rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, other)
    with ApparelWorld(other_rec.keypoints, other_physics.pieces, other_physics.chains, other.simulation,
                      1 / 120) as world:
        world.reset()
        simulate_motion(other_rec, other_physics, make_motion(other_rec, quick_turn(30, 2), "turn"), other, 120.0, 4,
                        world)
        used = world.client
    assert world_module._IDLE_CLIENTS == [used]
    with ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240) as world:
        assert world.client == used and not world_module._IDLE_CLIENTS
        world.reset()
        reused = simulate_motion(rec, physics, turn, params, 240.0, 8, world)[0].transforms
    assert reused.tobytes() == fresh.tobytes()
    monkeypatch.setattr(world_module, "MAX_IDLE_CLIENTS", 0)
    ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240).close()
    assert not world_module._IDLE_CLIENTS and not pybullet.isConnected(physicsClientId=used)


def test_chain_mass_matrix_predicts_bullets_response_to_joint_torques():
    # the springs' implicit step rests on the chain's joint-space mass matrix: a torque tau on the
    # joints of a still chain (no gravity, springs off) changes their speeds by dt M^-1 tau in one
    # Bullet step (M from the link geometry in numpy; the anchor, ten times heavier, barely moves)
    rec = make_character()
    params = params_from_json({"simulation": {"gravity": 0.0}})
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    chain = physics.chains[0]
    mass_matrix = chain_mass_matrix(chain)
    np.testing.assert_allclose(mass_matrix, mass_matrix.T, atol=1e-15)
    assert np.linalg.eigvalsh(mass_matrix).min() > 0
    rng = np.random.default_rng(0)
    with ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240) as world:
        pb, body, joints = world.pb, world.chains[0].body, list(range(LINKS))
        for _ in range(3):
            world.reset()
            tau = rng.normal(size=3 * LINKS) * 1e-3
            pb.setJointMotorControlMultiDofArray(body, joints, pb.TORQUE_CONTROL, forces=tau.reshape(-1, 3).tolist(),
                                                 physicsClientId=world.client)
            world.step()
            speeds = np.concatenate([s[1] for s in pb.getJointStatesMultiDof(body, joints,
                                                                              physicsClientId=world.client)])
            expected = np.linalg.solve(mass_matrix, tau) / 240
            np.testing.assert_allclose(speeds, expected, rtol=0.02, atol=0.02 * np.abs(expected).max())


def test_exploding_parameters_raise():
    params = params_from_json({"simulation": {"gravity": 10000.0}})
    with pytest.raises(SimulationExploded, match="m/s"):
        _simulate(quick_turn(20), params)


def test_urdf_matches_the_chain():
    rec = make_character()
    params = params_from_json({"kinds": {"skirt": {"swing_limit": 0.4, "twist_limit": 0.15}}})
    chain = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params).chains[0]
    assert chain.kind == "skirt" and chain.anchor_bone == 0 and chain.bones == [1, 2, 3, 4]
    root = ET.fromstring(chain_urdf(chain, chain.links[0].head))
    joints = root.findall("joint")
    assert [j.get("type") for j in joints] == ["spherical"] * LINKS
    for j in joints:
        lim = j.find("limit")
        assert float(lim.get("lower")) == pytest.approx(0.4) and float(lim.get("twist")) == pytest.approx(0.15)
    def rpy_matrix(text):  # URDF rpy = Rz(yaw) Ry(pitch) Rx(roll)
        r, p, y = np.array(text.split(), float)
        rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        return rz @ ry @ rx

    # the first joint turns the anchor's world-aligned frame so that +Z runs down the bone (-Y)
    np.testing.assert_allclose(rpy_matrix(joints[0].find("origin").get("rpy")) @ [0, 0, 1], [0, -1, 0], atol=1e-6)
    np.testing.assert_allclose(np.array(joints[0].find("origin").get("xyz").split(), float), 0, atol=1e-6)
    for j in joints[1:]:  # the next ones sit one link further along +Z, unturned
        np.testing.assert_allclose(rpy_matrix(j.find("origin").get("rpy")), np.eye(3), atol=1e-6)
        np.testing.assert_allclose(np.array(j.find("origin").get("xyz").split(), float), [0, 0, LINK], atol=1e-6)
    for link in root.findall("link")[1:]:
        col = link.find("collision")
        cap = col.find("geometry/capsule")
        assert float(cap.get("length")) == pytest.approx(LINK, rel=1e-5)
        assert 0.015 < float(cap.get("radius")) < 0.05  # the toy's cylinders have radius 0.02 (skirt scale 1.5)
        np.testing.assert_allclose(np.array(col.find("origin").get("xyz").split(), float), [0, 0, LINK / 2], atol=1e-6)


def test_links_collide_as_the_hull_of_their_vertices(tmp_path):
    rec = make_character()
    whole = params_from_json({"kinds": {"skirt": {"root_hull_from": 0.0}}})  # the skirt's root keeps its whole hull
    chain = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, whole).chains[0]
    owner = rec.weight_indices[:, 0]  # one-hot toy weights
    for link in chain.links:
        own = rec.vertices[owner == link.bone].astype(np.float64) - link.head
        # the hull's points are the cylinder's own vertices, and every vertex of it lies inside
        # their hull (scipy's Delaunay as the independent inside test)
        assert all(np.min(np.linalg.norm(own - p, axis=1)) < 1e-6 for p in link.hull)
        assert (Delaunay(link.hull).find_simplex(own, tol=1e-9) >= 0).all()
    obj = tmp_path / "l0.obj"
    obj.write_text(hull_obj(chain.links[0]))
    root = ET.fromstring(chain_urdf(chain, chain.links[0].head, hull_files=["l0.obj", None, None, None]))
    links = root.findall("link")[1:]
    assert links[0].find("collision/geometry/mesh").get("filename") == "l0.obj"
    assert links[1].find("collision/geometry/capsule") is not None
    # the OBJ's points are the hull in the link frame: Z down the bone (-Y), the head at 0
    pts = np.array([line.split()[1:] for line in obj.read_text().splitlines() if line.startswith("v ")], float)
    frame = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # the link frame: a quarter turn about X, +Z onto -Y
    np.testing.assert_allclose(pts @ frame.T, chain.links[0].hull, atol=1e-6)
    assert pts[:, 2].min() > -1e-6 and pts[:, 2].max() == pytest.approx(LINK, abs=1e-6)


def test_params_file_overrides_and_errors(tmp_path):
    f = tmp_path / "p.json"
    f.write_text(json.dumps({"kinds": {"hair": {"stiffness": 0.5}, "default": {"link_mass": 0.2}},
                             "simulation": {"max_speed": 9}}))
    p = load_params(f)
    assert p.for_kind("hair").stiffness == pytest.approx(0.5) and p.simulation.max_speed == pytest.approx(9.0)
    assert p.simulation.max_resettles == 5  # the default
    assert params_from_json({"simulation": {"max_resettles": 0}}).simulation.max_resettles == 0
    assert params_from_json({"simulation": {"max_resettles": 3.0}}).simulation.max_resettles == 3
    assert p.simulation.file_contact_frequency == 75.0  # an MMD file's contact springs by default (issue 52)
    assert (p.simulation.file_step_rate, p.simulation.file_erp, p.simulation.file_solver_iterations,
            p.simulation.file_sleeping, p.simulation.file_warmup) == (240.0, 0.2, 30, False, True)
    assert params_from_json({"simulation": {"file_contact_frequency": 75}}).simulation.file_contact_frequency == 75.0
    assert p.for_kind("sleeve").link_mass == pytest.approx(0.2)  # unknown kinds use the overridden default
    assert p.for_kind("hair").link_mass == pytest.approx(ApparelParams().for_kind("hair").link_mass)
    for bad, msg in (({"kinds": {"hair": {"stiffnes": 1}}}, "unknown field 'stiffnes'"),
                     ({"kinds": {"hair": {"stiffness": 2}}}, "expected a number >= 0 and <= 1"),
                     ({"physics": {}}, "unknown section"),
                     ({"kinds": {"hair": {"collide_body": 1}}}, "expected true or false"),
                     ({"simulation": {"max_resettles": -1}}, r"max_resettles: expected a number >= 0, got -1"),
                     ({"simulation": {"file_contact_frequency": -5}}, r"file_contact_frequency: expected a number >= 0"),
                     ({"simulation": {"file_step_rate": 0}}, r"file_step_rate: expected a number > 0"),
                     ({"simulation": {"file_erp": 1.5}}, r"file_erp: expected a number > 0 and <= 1"),
                     ({"simulation": {"file_solver_iterations": 0}}, r"file_solver_iterations: expected a number >= 1"),
                     ({"simulation": {"file_warmup": 1}}, "file_warmup: expected true or false"),
                     ({"simulation": {"max_resettles": 2.5}}, r"max_resettles: expected a whole number, got 2.5")):
        f.write_text(json.dumps(bad))
        with pytest.raises(UserError, match=msg):
            load_params(f)
    f.write_text("{not json")
    with pytest.raises(UserError, match="not valid JSON"):
        load_params(f)


def test_selection_by_globs_and_weights():
    names = ["Hips", "Hair_L_01", "hair_l_02", "Skirt.F.1", "LeftArm"]
    np.testing.assert_array_equal(bones_matching(names, ["*hair*", "skirt*"]), [0, 1, 1, 1, 0])
    dense = np.array([[1.0, 0, 0, 0, 0], [0.4, 0.6, 0, 0, 0], [0.5, 0.5, 0, 0, 0], [0, 0, 0.2, 0.2, 0.6]])
    np.testing.assert_array_equal(apparel_vertex_mask(dense, np.array([0, 1, 1, 1, 0], bool)), [0, 1, 0, 0])
    assert bone_kind("J_Sec_Coat_Tail_01", None) == "coat_tail"
    assert bone_kind("x", "apparel/cape/2/1") == "cape" and bone_kind("Spine", None) == "default"


def _hanging_chain(name: str, x: float, links: int, max_torque: float):
    from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec

    down = np.array([0.0, -1.0, 0.0])
    specs = tuple(LinkSpec(1 + i, np.array([x, 1.0 - 0.08 * i, 0.0]), down, 0.08, 0.015, 0.05 + 0.01 * i)
                  for i in range(links))
    joints = tuple(JointSpec(0.7, 0.2, 0.03, 0.4, max_torque) for _ in range(links))
    return ChainSpec(name, "skirt", 0, specs, tuple(range(-1, links - 1)), joints)


def _posed_mass_matrix(chain, rotation: np.ndarray) -> np.ndarray:
    """(3L, 3L) the joint-space mass matrix of ``chain`` with its joints at rotation vectors
    ``rotation`` (L, 3), its anchor fixed: each link's Jacobians from its world turn R_i = R_p T_i
    exp(r_i) (T_i its rest turn in the parent's frame, scipy's rotations) summed as m J_v^T J_v +
    J_w^T I J_w, one link and joint at a time (the naive form of joint_kernel's composite sums)."""
    from scipy.spatial.transform import Rotation

    from mimicbench.datagen.apparel.urdf import bone_frame, capsule_inertia

    n = len(chain.links)
    rest = [bone_frame(link.axis).as_matrix() for link in chain.links]
    turn, head = [None] * n, [None] * n
    for i, link in enumerate(chain.links):
        p = chain.link_parents[i]
        joint = Rotation.from_rotvec(rotation[i]).as_matrix()
        if p < 0:
            turn[i], head[i] = rest[i] @ joint, np.asarray(link.head, np.float64)
        else:
            turn[i] = turn[p] @ rest[p].T @ rest[i] @ joint
            head[i] = head[p] + turn[p] @ rest[p].T @ (np.asarray(link.head) - np.asarray(chain.links[p].head))
    out = np.zeros((3 * n, 3 * n))
    for i, link in enumerate(chain.links):
        centre = head[i] + turn[i] @ [0.0, 0.0, 0.5 * link.length]
        transverse, axial = capsule_inertia(link.mass, link.radius, link.length, link.axial_share)
        inertia = turn[i] @ np.diag([transverse, transverse, axial]) @ turn[i].T
        jv, jw = np.zeros((3, 3 * n)), np.zeros((3, 3 * n))
        j = i
        while j >= 0:
            d = centre - head[j]
            cross = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
            jw[:, 3 * j:3 * j + 3], jv[:, 3 * j:3 * j + 3] = turn[j], -cross @ turn[j]
            j = chain.link_parents[j]
        out += link.mass * jv.T @ jv + jw.T @ inertia @ jw
    return out


@pytest.mark.parametrize("lengths", [(3, 4), (4, 4)])  # trees zero-padded to the widest; all as wide
@pytest.mark.parametrize("max_torque", [1e6, 2e-3])  # the bound never reached; reached by some joints
def test_springs_of_merged_chains_match_one_dense_solve(max_torque, lengths):
    # chains on one anchor share a multibody (merged_by_anchor) and their springs are solved per
    # chain; the reference solves the merged chain's whole implicit step at once with LAPACK:
    # tau = -M (M + dt D)^-1 (K q + D w), K = s diag(M0) / dt^2, D = K dt + v diag(M0) / dt (M0 the
    # rest mass matrix, M the one at the joints' rotations q, from _posed_mass_matrix), and
    # where |tau| passes the bound, K and D of that axis scaled by bound / |tau| and solved again
    from mimicbench.datagen.apparel.springs import Springs
    from mimicbench.datagen.apparel.chain_spec import merged_by_anchor

    dt = 1 / 240
    merged = merged_by_anchor([_hanging_chain("a", 0.2, lengths[0], max_torque),
                               _hanging_chain("b", -0.2, lengths[1], max_torque)])
    links = sum(lengths)
    assert len(merged) == 1 and len(merged[0].links) == links
    rng = np.random.default_rng(1)
    rotation, velocity = rng.normal(size=(links, 3)) * 0.3, rng.normal(size=(links, 3)) * 2.0
    springs = Springs(merged, dt)
    got = springs.torques(rotation, velocity).ravel()

    rest = chain_mass_matrix(merged[0])
    m = _posed_mass_matrix(merged[0], rotation)
    k = 0.03 * np.diag(rest) / dt ** 2
    d = k * dt + 0.4 * np.diag(rest) / dt
    q, w = rotation.ravel(), velocity.ravel()

    def dense(k, d):
        return -m @ np.linalg.solve(m + dt * np.diag(d), k * q + d * w)

    expected = dense(k, d)
    share = 1.0 / np.maximum(np.abs(expected) / max_torque, 1.0)
    if max_torque < 1:
        assert share.min() < 0.5 and springs.resolved > 0
        expected = dense(k * share, d * share)
    else:
        assert springs.resolved == 0
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_substep_poses_are_the_frame_by_frame_blends():
    # a clip's substep poses are computed for many frames at once; they must be the very numbers
    # of blending each frame from the one before it (the first from the given previous pose)
    from mimicbench.datagen.apparel.relax import blend_poses, substep_poses

    rng = np.random.default_rng(2)
    q = rng.normal(size=(6, 5, 4))
    poses = np.concatenate([q / np.linalg.norm(q, axis=-1, keepdims=True), rng.normal(size=(6, 5, 3))], axis=-1)
    previous = poses[0] * np.array([-1, -1, -1, -1, 1, 1, 1])  # the same rotations with the other sign
    got = substep_poses(previous, poses[1:], 8)
    loop, before = [], previous
    for pose in poses[1:]:
        loop.append(blend_poses(before, pose, np.arange(1, 9) / 8))
        before = pose
    assert got.shape == (5 * 8, 5, 7)
    assert got.tobytes() == np.concatenate(loop).tobytes()
    # each frame's last substep is the frame itself (a rotation up to its sign)
    np.testing.assert_allclose(np.abs(np.einsum("fkc,fkc->fk", got[7::8, :, :4], poses[1:, :, :4])), 1.0, atol=1e-12)
    np.testing.assert_allclose(got[7::8, :, 4:], poses[1:, :, 4:], atol=1e-12)


def test_joint_kernel_rotation_vectors_and_limit_count_match_scipy_and_a_naive_loop():
    # the compiled per-step arithmetic: rotation vectors of the joint quaternions (either sign of
    # a quaternion is the same rotation) against scipy's as_rotvec, and the number of joints past
    # a swing cone or twist bound against a plain loop; below every joint's floor none is counted
    from scipy.spatial.transform import Rotation

    from mimicbench.datagen.apparel.joint_kernel import rotation_vectors

    rng = np.random.default_rng(3)
    joints = 40
    rotvec = rng.normal(size=(joints, 3)) * rng.uniform(0.0, 1.2, size=(joints, 1))
    rotvec[0] = 0.0  # the identity
    quats = Rotation.from_rotvec(rotvec).as_quat()  # (x, y, z, w), w >= 0
    quats[::3] *= -1.0  # the other sign of the same rotation
    states = np.concatenate([quats, rng.normal(size=(joints, 3))], axis=1)
    swing, twist = rng.uniform(0.3, 0.9, joints), rng.uniform(0.1, 0.5, joints)
    floor = np.minimum(swing, twist) * (1.0 - 1e-9)
    got = np.empty((joints, 3))
    over = rotation_vectors(states.copy(), floor, swing, twist, got)
    np.testing.assert_allclose(got, rotvec, atol=1e-12)
    naive = sum(1 for (x, y, z), s, t in zip(rotvec, swing, twist) if (x * x + y * y) ** 0.5 > s or abs(z) > t)
    assert over == naive and 0 < naive < joints
    assert rotation_vectors(states.copy(), np.full(joints, 10.0), swing, twist, got) == 0


STRIP = np.array([[x, y, z] for x in (-0.04, 0.04) for y in (0.0, -0.08) for z in (-0.005, 0.005)])
"""A strip link's hull corners (8, 3), metres: 8 cm wide, 1 cm thick, in a link's frame (from its
head, the bone along -Y)."""


def _strip_and_box(box_head, box_half, speed: float, kind: str, mass: float, joint: tuple, fps: float = 30.0,
                   frames: int = 60, box_turn: float = 0.0, axial_share: float = 1.0,
                   root_contact_frequency: float = 0.0, contact_frequency: float = 0.0,
                   piece_velocity: bool = True) -> np.ndarray:
    """A strip of 4 links (:data:`STRIP` hulls, 8 cm long, ``mass`` kg each, joints
    ``JointSpec(*joint)``, apparel kind ``kind``) hanging from bone 0 at 1 m, and a box (bone 1, half
    extents ``box_half`` (3,) m, its centre ``box_head`` (3,) m, turned ``box_turn`` rad about Y),
    moved 3 cm along -Z at ``speed`` m/s from frame 10, then held. The root link's contacts are a
    spring of ``root_contact_frequency`` rad/s, the other links' of ``contact_frequency`` (0: Bullet's
    rigid contact). ``piece_velocity``: the box carries its speed (simulation version 13) or is a
    static body placed each step (version 12, :class:`~mimicbench.datagen.apparel.params.SimParams`).

    Returns the simulated clip (F, 6, 7), 8 substeps a frame at ``fps``."""
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
    from mimicbench.datagen.apparel.params import SimParams
    from mimicbench.datagen.apparel.simulate import simulate_clip
    from mimicbench.geometry.kinematics import rest_transforms

    heads = np.array([[0.0, 1.0 - 0.08 * i, 0.0] for i in range(4)])
    box_head = np.asarray(box_head, np.float64)
    keypoints = np.concatenate([[[0.0, 1.0, 0.0]], [box_head], heads])
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.asarray(box_half)
    pieces = body_pieces(corners + box_head, keypoints, np.ones(8, int), np.array([False, True] + [False] * 4))
    links = tuple(LinkSpec(2 + i, heads[i], np.array([0.0, -1.0, 0.0]), 0.08, 0.01, mass, hull=STRIP,
                           axial_share=axial_share,
                           contact_frequency=root_contact_frequency if i == 0 else contact_frequency)
                  for i in range(4))
    chain = ChainSpec("strip", kind, 0, links, (-1, 0, 1, 2), tuple(JointSpec(*joint) for _ in range(4)))
    clip = np.repeat(rest_transforms(keypoints).astype(np.float64)[None], frames, axis=0)
    clip[:, 1, 6] -= np.clip((np.arange(frames) - 10) / fps * speed, 0.0, 0.03)
    if box_turn:
        clip[:, 1, :4] = [np.cos(box_turn / 2), 0.0, np.sin(box_turn / 2), 0.0]
    with ApparelWorld(keypoints, pieces, [chain], SimParams(piece_velocity=piece_velocity), 1.0 / (fps * 8)) as world:
        return simulate_clip(world, clip, 8, 0).transforms


def _strip_accelerations(sim: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The strip links' rotations (F, 4, 3, 3) of a clip (F, 6, 7) of :func:`_strip_and_box`, and the
    accelerations (F-2, 4, 8) m/s^2 of their hull corners at frames 1..F-2 (second differences)."""
    rot = np.array([[_hand_rotation(qf) for qf in frame] for frame in sim[:, 2:, :4].astype(np.float64)])
    corners = np.einsum("flab,pb->flpa", rot, STRIP) + sim[:, 2:, None, 4:].astype(np.float64)
    return rot, np.linalg.norm(corners[2:] - 2 * corners[1:-1] + corners[:-2], axis=-1) * fps ** 2


def _strip_pressed_by_a_box(axial_share: float, fps: float = 30.0, piece_velocity: bool = True) -> np.ndarray:
    """A flat strip (twist limit 0.2 rad, 0.02 kg links) and a box 12 x 36 x 4 cm turned 0.4 rad
    about Y in front of it, moved at 0.3 m/s: its near edge meets one edge of the strip first, so
    the contact turns the strip about its bone and keeps pressing it past its 0.2 rad twist limit
    toward the box's 0.4 rad. Returns the clip (F, 6, 7)."""
    return _strip_and_box([0.0, 0.84, 0.06], [0.06, 0.18, 0.02], 0.3, "hair", 0.02, (0.8, 0.2, 0.02, 0.3, 0.05),
                          fps, box_turn=0.4, axial_share=axial_share, piece_velocity=piece_velocity)


def test_twist_limit_holds_under_a_contact_pressing_against_it_without_jitter():
    # issue 33: contacts twisted thin links past their twist limit and the per-step projection put
    # them back into the body, step after step. Here a box presses a strip past its 0.2 rad twist
    # limit and holds it there. Bound from the scene: once the box stands still (frame 13) and the
    # strip has settled (half a second), nothing moves but what gravity and the strip's springs
    # move, so no point of it may accelerate faster than gravity (9.8 m/s^2); with a thin
    # capsule's own axial inertia (simulation version 8) the strip kept shaking above it (since
    # version 12's springs at the present pose just below it, 8.4 m/s^2, still more than with
    # axial inertia 1, 5.9). With version 13's box that carries its speed the thin capsule settles
    # too (1.2 m/s^2), so the fight is shown on version 12's static box
    fps = 30.0
    peaks = {}
    for share, piece_velocity in ((1.0, True), (0.0, False)):
        sim = _strip_pressed_by_a_box(share, fps, piece_velocity)
        rot, accel = _strip_accelerations(sim, fps)  # (F, 4, 3, 3) links' rotations; frames 1..F-2
        peaks[share] = accel[13 + 15 - 1:].max()  # from frame 28 on
        if share == 1.0:
            # joint i's rotation is R_parent^T R_i (every link's rest frame points down -Y), its
            # twist the rotation vector's component along the bone
            twists = np.zeros((len(sim), 4))
            for f in range(len(sim)):
                parent = np.eye(3)
                for i in range(4):
                    rel = parent.T @ rot[f, i]
                    angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
                    axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
                    twists[f, i] = abs(angle * axis[1] / max(np.linalg.norm(axis), 1e-12))
                    parent = rot[f, i]
            assert twists.max() < 0.2 + 0.01  # held at the limit
            assert twists[-1].max() > 0.19  # and the box still presses it there at the end
    assert peaks[1.0] < 9.8, peaks
    assert peaks[0.0] > 1.2 * peaks[1.0], peaks  # the scene shows the fight where there is one


@pytest.mark.parametrize("frames", [20, 200])
def test_quality_accelerations_peak_and_99th_percentile_by_hand(frames):
    # the toy's tip bone (a quarter of the apparel vertices, one-hot weights) jumps into a steady
    # drift of d per frame after frame 5: every tip vertex's second difference is d at frame 5 and 0
    # elsewhere, so the peak is d fps^2; of the (frames - 2) x A accelerations a share of
    # 1 / (4 (frames - 2)) is nonzero: above 1% (frames 20) the 99th percentile is the peak too,
    # below it (frames 200) it is 0
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.quality import clip_quality
    from mimicbench.geometry.kinematics import rest_transforms

    rec = make_character()
    fps, d = 30.0, 0.01
    kinematic = np.repeat(rest_transforms(rec.keypoints)[None], frames, axis=0).astype(np.float32)
    simulated = kinematic.copy()
    simulated[:, LINKS, 4] += d * np.clip(np.arange(frames) - 5, 0, None)
    owner = rec.weight_indices[:, 0]
    apparel = np.asarray(rec.apparel_vertex_mask, bool)
    assert np.isclose((owner[apparel] == LINKS).mean(), 0.25)
    pieces = body_pieces(rec.vertices, rec.keypoints, owner, ~np.asarray(rec.apparel_bone_mask, bool))
    q = clip_quality(rec.vertices, rec.faces, rec.keypoints, rec.weights, apparel, pieces, simulated, kinematic,
                     fps, rec.height)
    assert q["max_accel"] == pytest.approx(d * fps ** 2, rel=1e-4)
    # float32 vertices near 1 m: rounding noise of about 1e-4 m/s^2 at 30 fps
    assert q["p99_accel"] == pytest.approx(d * fps ** 2 if frames == 20 else 0.0, rel=1e-4, abs=1e-3)
    assert q["max_accel_kinematic"] < 1e-3 and q["p99_accel_kinematic"] < 1e-3
    assert q["max_accel_kinematic_body"] < 1e-3


def test_quality_kinematic_body_peak_by_hand():
    # issue 33: a limb striking the apparel (a thigh at a jump's landing) moves faster than the
    # apparel's own kinematic clip, so the quality records the body's kinematic peak too. The toy's
    # torso (bone 0, one-hot weights, every body vertex) jumps into a drift of d per frame after frame
    # 5 in the kinematic clip while the chain's bones stay: every torso vertex's second difference is
    # d at frame 5, so the body's peak is d fps^2 and the apparel's stays 0 (rounding only)
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.quality import clip_quality
    from mimicbench.geometry.kinematics import rest_transforms

    rec = make_character()
    fps, d, frames = 30.0, 0.02, 20
    kinematic = np.repeat(rest_transforms(rec.keypoints)[None], frames, axis=0).astype(np.float32)
    kinematic[:, 0, 4] += d * np.clip(np.arange(frames) - 5, 0, None)
    owner = rec.weight_indices[:, 0]
    apparel = np.asarray(rec.apparel_vertex_mask, bool)
    assert (owner[~apparel] == 0).all()
    pieces = body_pieces(rec.vertices, rec.keypoints, owner, ~np.asarray(rec.apparel_bone_mask, bool))
    q = clip_quality(rec.vertices, rec.faces, rec.keypoints, rec.weights, apparel, pieces, kinematic, kinematic,
                     fps, rec.height)
    assert q["max_accel_kinematic_body"] == pytest.approx(d * fps ** 2, rel=1e-4)
    assert q["max_accel_kinematic"] < 1e-3 and q["max_accel"] < 1e-3


@pytest.mark.parametrize("axis, touches", [(4, True), (6, False)])
def test_quality_touching_peak_counts_only_limbs_that_reach_the_apparel(axis, touches):
    # the toy's torso box (x in [-0.15, 0.15], z in [-0.1, 0.1]) is 8 cm from the chain's cylinders
    # (x in [0.23, 0.27], 2 cm radius) at rest, farther than TOUCH_SHARE x height (1.6 cm). It jumps
    # into a drift of d = 2 cm per frame after frame 5: along +X it runs through the chain (every torso
    # vertex accelerates by d fps^2 at frame 5 and some come within reach), along +Z it passes beside
    # it (its nearest vertex stays 8 cm off in X), so the touching peak is d fps^2 or 0 while the
    # body's peak is d fps^2 either way; a strike's peak over 3x the apparel's is jitter only when it
    # is also over 3x the touching limbs' peak
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.quality import TOUCH_SHARE, clip_quality, over_jitter_bound
    from mimicbench.geometry.kinematics import rest_transforms

    rec = make_character()
    assert TOUCH_SHARE * rec.height < 0.08
    fps, d, frames = 30.0, 0.02, 20
    kinematic = np.repeat(rest_transforms(rec.keypoints)[None], frames, axis=0).astype(np.float32)
    kinematic[:, 0, axis] += d * np.clip(np.arange(frames) - 5, 0, None)
    owner = rec.weight_indices[:, 0]
    apparel = np.asarray(rec.apparel_vertex_mask, bool)
    pieces = body_pieces(rec.vertices, rec.keypoints, owner, ~np.asarray(rec.apparel_bone_mask, bool))
    q = clip_quality(rec.vertices, rec.faces, rec.keypoints, rec.weights, apparel, pieces, kinematic, kinematic,
                     fps, rec.height)
    assert q["max_accel_kinematic_body"] == pytest.approx(d * fps ** 2, rel=1e-4)
    assert q["max_accel_kinematic_touching"] == pytest.approx(d * fps ** 2 if touches else 0.0, rel=1e-4, abs=1e-3)
    # the pieces are tested a few frames at a time, stopping at a piece's first touch: the torso
    # reaches the chain only some frames after the drift starts, so small chunks see it late
    from mimicbench.datagen.apparel.quality import _touched_bones
    from mimicbench.geometry.skinning import linear_blend_skinning

    posed = linear_blend_skinning(rec.vertices, rec.keypoints, rec.weights, kinematic).astype(np.float64)[:, apparel]
    for chunk in (1, 3, frames):
        assert _touched_bones(pieces, kinematic.astype(np.float64), posed, 0.02 * rec.height, chunk) == \
            ([0] if touches else [])
    struck = q | {"max_accel": 2.0 * d * fps ** 2, "max_accel_kinematic": 1.0}  # a strike twice the limb's peak
    assert over_jitter_bound(struck) is (not touches)
    assert over_jitter_bound(struck | {"max_accel": 4.0 * d * fps ** 2}) is True


@pytest.mark.parametrize("piece_mass, piece_velocity", [(0.0, False), (0.0, True), (100.0, True)])
def test_body_pieces_with_mass_are_carried_at_the_limbs_speed(piece_mass, piece_velocity):
    # the torso slides along +X at 0.5 m/s (a clip of 240 Hz steps): a static piece (piece_velocity
    # off, simulation version 12) is placed at each step's pose and has no speed; a moving one
    # (version 13's default) ends each step at its pose with the torso's speed; a piece with mass is
    # carried there by its constraint and moves at the torso's speed, a few millimetres behind its
    # pose at most
    from mimicbench.geometry.kinematics import rest_transforms

    rec = make_character()
    params = params_from_json({"simulation": {"piece_mass": piece_mass, "piece_velocity": piece_velocity}})
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    steps = np.repeat(rest_transforms(rec.keypoints)[None].astype(np.float64), 120, axis=0)
    steps[..., 4] += 0.5 * np.arange(1, 121)[:, None] / 240
    with ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240) as world:
        world.start()
        for _ in world.follow(steps, 120):
            pass
        body = world.piece_ids[0]
        where = np.array(world.pb.getBasePositionAndOrientation(body, physicsClientId=world.client)[0])
        speed = np.array(world.pb.getBaseVelocity(body, physicsClientId=world.client)[0])
    np.testing.assert_allclose(where, steps[-1, 0, 4:], atol=5e-3)
    np.testing.assert_allclose(speed, [0.5 if piece_mass or piece_velocity else 0.0, 0.0, 0.0], atol=0.02)


def _root_struck_by_a_box(contact_frequency: float, fps: float = 30.0):
    """A skirt-like strip (0.05 kg links, twist limit 0.1 rad) and a box 12 x 6 x 4 cm in front of its
    root link, 5 mm away, moved through where the root link hangs at 0.5 m/s: a thigh swinging into
    a skirt's top. The root link's contacts are a spring of ``contact_frequency`` rad/s (0: rigid).

    Returns the largest acceleration (m/s^2) of the strip's hull corners over the clip and from
    frame 31 on (the box held still since frame 16)."""
    sim = _strip_and_box([0.0, 0.96, 0.03], [0.06, 0.03, 0.02], 0.5, "skirt", 0.05, (0.7, 0.1, 0.03, 0.4, 0.2), fps,
                         root_contact_frequency=contact_frequency)
    accel = _strip_accelerations(sim, fps)[1]
    return accel.max(), accel[30:].max()


def test_a_box_striking_a_strips_root_link_through_a_soft_contact_does_not_throw_the_strip():
    # issue 33, simulation version 10: a thigh placed anew each step starts the step inside a
    # skirt strip's root link (held at the hip, it cannot get out of the way), and Bullet's rigid
    # contact pushed it out within one step, throwing the strip (zoo tips at 5-10 m/s, alternating
    # step by step). Bound from the scene: through a critically damped contact spring of
    # frequency w on the root link's mass m, a box arriving at v = 0.5 m/s accelerates the link
    # by at most w^2 x + 2 w x' <= 2 w v (x, the depth, grows as v t e^{-w t}), 150 m/s^2 at the
    # skirt's w = 150 rad/s; once the box stands still, nothing moves but what gravity and the
    # springs move, so no point may accelerate faster than gravity (9.8 m/s^2)
    w = ApparelParams().for_kind("skirt").root_contact_frequency
    assert w == 150.0
    peak, held = _root_struck_by_a_box(w)
    assert peak < 2 * w * 0.5, peak
    assert held < 9.8, held
    rigid_peak, rigid_held = _root_struck_by_a_box(0.0)
    assert rigid_peak > 2 * w * 0.5 and rigid_held > 9.8, (rigid_peak, rigid_held)  # the scene shows the throw


class _Kicked:
    """A world (delegated to) whose chain multibody ``body`` is struck after each clip frame of
    ``frames`` (counted from the first simulated frame): its base gets the linear velocity ``kick``
    (3,) m/s just before the frame is read. ``resettle`` calls' counts are kept in :attr:`counts`."""

    def __init__(self, world, body: int, frames, kick):
        self.world, self.body, self.frames, self.kick = world, body, set(frames), list(kick)
        self.seen, self.counts = 0, []

    def __getattr__(self, name):
        return getattr(self.world, name)

    def follow(self, poses, per_frame):
        for f in self.world.follow(poses, per_frame):
            if self.seen in self.frames:
                self.world.pb.resetBaseVelocity(self.body, linearVelocity=self.kick, physicsClientId=self.world.client)
            self.seen += 1
            yield f

    def resettle(self, pose):
        self.counts.append(self.world.resettle(pose))
        return self.counts[-1]


TWO_STRIP_ANCHORS = np.array([[0.0, 1.0, 0.0], [0.5, 1.0, 0.0]])  # bones 0 and 1: the body


def _two_strips(kicks=(), kick=(40.0, 0.0, 0.0), max_resettles: int = 5, frames: int = 40, relax: int = 0):
    """Two 4-link strips (:data:`STRIP` hulls, 8 cm links, 0.03 kg), one hanging from each of the
    body bones 0 and 1 (:data:`TWO_STRIP_ANCHORS`); no body pieces. The body turns about Y through
    bone 0 at 3 rad/s for 10 frames at 30 fps, then holds (strip A, on bone 0 and bones 2-5, hangs on
    the axis; strip B, on bone 1 and bones 6-9, swings). Strip B is struck at ``kicks`` (frames counted from the first simulated one: relaxation frames first) with base
    velocity ``kick`` m/s.

    Returns (keypoints (10, 3), clip (F, 10, 7), the simulated clip, the kicked world's resettle counts)."""
    from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
    from mimicbench.datagen.apparel.params import SimParams
    from mimicbench.datagen.apparel.simulate import simulate_clip
    from tests.apparel_toys import turn_about_y

    chains, heads = [], []
    for a, anchor in enumerate(TWO_STRIP_ANCHORS):
        strip = np.array([anchor + [0.0, -0.08 * i, 0.0] for i in range(4)])
        heads.append(strip)
        links = tuple(LinkSpec(2 + 4 * a + i, strip[i], np.array([0.0, -1.0, 0.0]), 0.08, 0.01, 0.03, hull=STRIP,
                               axial_share=1.0) for i in range(4))
        chains.append(ChainSpec(f"strip{a}", "hair", a, links, (-1, 0, 1, 2),
                                tuple(JointSpec(0.8, 0.2, 0.02, 0.3, 0.05) for _ in range(4))))
    keypoints = np.concatenate([TWO_STRIP_ANCHORS, *heads])
    clip = turn_about_y(np.minimum(np.arange(frames), 10) * 0.1, keypoints).astype(np.float64)
    with ApparelWorld(keypoints, [], chains, SimParams(), 1.0 / 240) as world:
        assert [c.spec.anchor_bone for c in world.chains] == [0, 1]  # two multibodies
        kicked = _Kicked(world, world.chains[1].body, kicks, kick)
        return keypoints, clip, simulate_clip(kicked, clip, 8, relax, max_resettles), kicked.counts


def test_a_struck_chain_is_resettled_at_rest_on_its_anchor_and_the_clip_goes_on():
    n = 12  # strip B swings behind its turned bone
    keypoints, clip, plain, _ = _two_strips()
    assert plain.resettled_frames == []
    _, _, struck, counts = _two_strips([n])
    assert struck.resettled_frames == [n] and counts == [1]  # one chain, strip B
    a, b = slice(2, 6), slice(6, 10)
    assert struck.transforms[:n].tobytes() == plain.transforms[:n].tobytes()
    assert struck.transforms[n, a].tobytes() == plain.transforms[n, a].tobytes()  # strip A untouched
    assert struck.transforms[:, a].tobytes() == plain.transforms[:, a].tobytes()  # then too (its springs kept)
    assert np.abs(plain.transforms[n:, a] - plain.transforms[n, a]).max() > 0.01  # while it moves
    assert np.isfinite(struck.transforms).all()
    # strip B at rest on bone 1: each bone turned as bone 1 is (about Y), heads carried rigidly with it
    q = clip[n, 1, :4]
    expected_heads = (keypoints[b] - keypoints[1]) @ _hand_rotation(q).T + clip[n, 1, 4:]
    np.testing.assert_allclose(struck.transforms[n, b, 4:], expected_heads, atol=1e-6)
    sign = np.sign(struck.transforms[n, b, :1] * q[0])  # q and -q: one rotation
    np.testing.assert_allclose(struck.transforms[n, b, :4] * sign, np.broadcast_to(q, (4, 4)), atol=1e-6)
    assert np.abs(plain.transforms[n, b, 4:] - expected_heads).max() > 0.01  # unstruck, it had swung off rest
    assert np.abs(struck.transforms[n + 1:, b] - plain.transforms[n + 1:, b]).max() > 1e-3


def test_more_escapes_than_max_resettles_fail_the_clip():
    _, _, struck, counts = _two_strips([5, 12, 20], max_resettles=3)
    assert struck.resettled_frames == [5, 12, 20] and counts == [1, 1, 1]
    with pytest.raises(SimulationExploded, match=r"^a link reached \d+\.\d m/s at frame 20 \(bound 25 m/s\) "
                                                 r"after 2 re-settles \(max_resettles 2\)$"):
        _two_strips([5, 12, 20], max_resettles=2)
    # 0: as at simulation version 10, the first escape fails the clip, with version 10's message
    with pytest.raises(SimulationExploded, match=r"^a link reached \d+\.\d m/s at frame 5 \(bound 25 m/s\)$"):
        _two_strips([5, 12, 20], max_resettles=0)


def test_relaxation_frames_are_resettled_as_negative_frames():
    # 6 relaxation frames then the clip: struck at the fourth relaxation frame (index 3) and at clip frame 2
    _, _, struck, _ = _two_strips([3, 8], relax=6)
    assert struck.resettled_frames == [-3, 2]
    with pytest.raises(SimulationExploded, match=r"at relaxation frame 4 of 6 \(bound 25 m/s\)$"):
        _two_strips([3, 8], relax=6, max_resettles=0)


def test_a_nan_state_is_resettled_like_an_escape():
    # chose: a chain whose state is not finite is put back at rest like a fast one (the NaN is
    # read before any step sees it, so the next steps are finite)
    n = 12
    keypoints, clip, plain, _ = _two_strips()
    _, _, struck, counts = _two_strips([n], kick=(np.nan, 0.0, 0.0))
    assert struck.resettled_frames == [n] and counts == [1]
    assert np.isfinite(struck.transforms).all()
    assert struck.transforms[:n].tobytes() == plain.transforms[:n].tobytes()
    np.testing.assert_allclose(struck.transforms[n, 6:10, 4:],
                               (keypoints[6:10] - keypoints[1]) @ _hand_rotation(clip[n, 1, :4]).T + clip[n, 1, 4:],
                               atol=1e-6)
    with pytest.raises(SimulationExploded, match=r"^NaN in the simulation at frame 12$"):
        _two_strips([n], kick=(np.nan, 0.0, 0.0), max_resettles=0)


def test_a_state_still_bad_right_after_resettling_fails_the_clip():
    from mimicbench.datagen.apparel.simulate import simulate_clip

    class Unfixed(_Kicked):  # its re-settle puts nothing back
        def resettle(self, pose):
            return 0

    rec = make_character()
    params = ApparelParams()
    physics = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, params)
    clip = make_motion(rec, np.zeros(20)).transforms
    with ApparelWorld(rec.keypoints, physics.pieces, physics.chains, params.simulation, 1 / 240) as world:
        with pytest.raises(SimulationExploded, match=r"^a link reached \d+\.\d m/s at frame 7 \(bound 25 m/s\) right "
                                                     r"after re-settling its chains, 0 re-settles before \(max_resettles 5\)$"):
            simulate_clip(Unfixed(world, world.chains[0].body, [7], [40.0, 0, 0]), clip, 8, 0)


def test_cut_near_pivot_clips_the_hull_at_a_share_of_the_link():
    # a link 10 cm long down -Y whose hull is a 2 x 2 cm box (its 8 corners, at 0 and 10 cm along the
    # bone): a share 0.3 clips it at 3 cm, the box from 3 to 10 cm (8 corners: 4 kept, 4 where the
    # side edges cross the plane); share 0 keeps the hull as it is, as does a share whose part spans
    # no volume (1: the bottom face alone)
    from mimicbench.datagen.apparel.chains import cut_near_pivot

    axis, length = np.array([0.0, -1.0, 0.0]), 0.1
    hull = np.array([[x, -y, z] for y in (0.0, 0.1) for x in (-0.01, 0.01) for z in (-0.01, 0.01)])
    cut = cut_near_pivot(hull, axis, length, 0.3)
    expected = np.array([[x, -y, z] for y in (0.03, 0.1) for x in (-0.01, 0.01) for z in (-0.01, 0.01)])
    assert len(cut) == 8
    assert np.abs(np.sort(cut.round(9), axis=0) - np.sort(expected, axis=0)).max() < 1e-12
    assert cut_near_pivot(hull, axis, length, 0.0) is hull
    assert cut_near_pivot(hull, axis, length, 1.0) is hull
    assert cut_near_pivot(None, axis, length, 0.3) is None
    # a link's hull keeps at most MAX_LINK_HULL_POINTS points, the clipped one too (a ball of 400
    # points on its surface clipped through its middle has over 200 hull points)
    from mimicbench.datagen.apparel.chains import MAX_LINK_HULL_POINTS

    rng = np.random.default_rng(0)
    ball = rng.normal(size=(400, 3))
    ball = 0.05 * ball / np.linalg.norm(ball, axis=1, keepdims=True) + [0.0, -0.05, 0.0]
    clipped = cut_near_pivot(ball, axis, length, 0.5)
    assert len(clipped) <= MAX_LINK_HULL_POINTS and (clipped @ axis).min() >= 0.05 - 1e-9


def test_skirt_roots_collide_only_beyond_root_hull_from():
    # the skirt kind's root link (and the coat tail's) keeps its hull 30 % of its length or more from the hip pivot
    # (simulation version 14); its other links, and every link of a kind with root_hull_from 0,
    # keep their whole hull
    rec = make_character()
    cut = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask, ApparelParams()).chains
    whole = character_physics(rec, rec.apparel_bone_mask, rec.apparel_vertex_mask,
                              params_from_json({"kinds": {"skirt": {"root_hull_from": 0.0}}})).chains
    kinds = ApparelParams()
    assert kinds.for_kind("skirt").root_hull_from == kinds.for_kind("coat_tail").root_hull_from == 0.3
    assert kinds.for_kind("hair").root_hull_from == kinds.for_kind("cape").root_hull_from == 0
    (chain,), (full,) = cut, whole
    assert chain.kind == "skirt" and chain.link_parents[0] == -1
    root, root_full = chain.links[0], full.links[0]
    assert (root_full.hull @ root_full.axis).min() < 0.3 * root_full.length
    assert (root.hull @ root.axis).min() >= 0.3 * root.length - 1e-9
    for a, b in zip(chain.links[1:], full.links[1:]):
        assert np.array_equal(a.hull, b.hull)
