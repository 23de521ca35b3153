"""The zoo's ``dynamic`` clip set: each motion checked against a hand-computable property of its root.

Every figure is computed here from the stored transforms (quaternion + position per joint) and
the constants the module states (angles, gravity, shares of the height), never from the
generator's own intermediate arrays.
"""
import numpy as np
import pytest

from mimicbench.datagen.zoo.dataset import build_zoo
from mimicbench.datagen.zoo.build import build_character, clip_list
from mimicbench.datagen.zoo.clips import (DYNAMIC_CLIPS, GRAVITY, JUMP_HEIGHT, SPIN_ANGLE, STOP_FRAMES, TURN_ANGLE,
                               clip_names, jump_timing, stop_frame)
from mimicbench.datagen.zoo.motions import FPS, RAMP_FRAMES
from mimicbench.datagen.zoo.plan import plan_zoo
from mimicbench.geometry.kinematics import array_to_transforms
from mimicbench.geometry.quaternion import quat_apply

FRAMES = 60
SPECS = [s for s in plan_zoo(20, seed=3, categories=["apparel", "humanoid"]) if s.index in (0, 1)]


@pytest.fixture(scope="module", params=[s.character_id for s in SPECS])
def built(request):
    spec = next(s for s in SPECS if s.character_id == request.param)
    b = build_character(spec, "train", len(DYNAMIC_CLIPS), FRAMES, clip_set="dynamic")
    return b, {m.name: array_to_transforms(m.transforms) for m in b.motions}


def _root(b) -> int:
    return int(np.flatnonzero(b.record.parents < 0)[0])


def _yaw(q_root: np.ndarray) -> np.ndarray:
    """Unwrapped heading (F,) of the root: the angle of its rotated forward axis (Z) about Y."""
    z = quat_apply(q_root, np.array([0.0, 0.0, 1.0]))
    return np.unwrap(np.arctan2(z[:, 0], z[:, 2]))


def _height(b) -> float:
    return float(np.ptp(np.concatenate([b.skeleton.heads, b.skeleton.tails])[:, 1]))


def test_dynamic_set_gives_the_four_motions_first(built):
    b, _ = built
    assert [m.name for m in b.motions] == ["spin", "stop", "jump", "turn"]
    assert [m.motion_id for m in b.motions] == [f"{b.record.character_id}/{n}" for n in DYNAMIC_CLIPS]


def test_spin_turns_the_root_by_the_stated_angle_on_the_spot(built):
    b, clips = built
    q, p = clips["spin"]
    r = _root(b)
    yaw = _yaw(q[:, r])
    assert abs(yaw[-1] - yaw[0]) == pytest.approx(SPIN_ANGLE, abs=1e-3)  # one full turn, either way
    steps = np.diff(yaw) * np.sign(yaw[-1])
    assert steps.min() > -1e-5 and steps.max() < np.pi / 2  # one way, never a jump of a quarter turn a frame
    assert np.abs(yaw[:RAMP_FRAMES + 1]).max() < 1e-5  # starts after the blend-in ramp
    assert np.abs(p[:, r] - p[0, r]).max() < 1e-5  # on the spot
    # turning stops before the end: the last frames hold the final heading
    assert np.abs(np.diff(yaw[int(0.8 * FRAMES) + 1:])).max() < 1e-5


def test_stop_leaves_zero_root_velocity_after_it(built):
    b, clips = built
    q, p = clips["stop"]
    r = _root(b)
    s = stop_frame(FRAMES)
    v = np.diff(p[:, r], axis=0) * FPS  # (F-1, 3) m/s, v[i] from frame i to i+1
    walking = 0.55 * _height(b) * 1.4  # the stated brisk-walk speed, m/s
    assert np.linalg.norm(v[RAMP_FRAMES:s], axis=1) == pytest.approx(np.full(s - RAMP_FRAMES, walking), rel=2e-3)
    assert np.abs(v[s + STOP_FRAMES:]).max() < 1e-4  # dead still after the stop
    # and the whole body stands in the rest pose: every joint at rest, shifted by the root's offset
    rest = b.record.keypoints.astype(np.float64)
    after = p[s + STOP_FRAMES:] - (p[s + STOP_FRAMES:, r] - rest[r])[:, None]
    assert np.abs(after - rest[None]).max() < 1e-4


def test_jump_leaves_the_ground_in_free_fall(built):
    b, clips = built
    _, p = clips["jump"]
    r = _root(b)
    H = _height(b)
    j = jump_timing(H)
    t = np.arange(FRAMES) / FPS
    air = np.flatnonzero((t > j["takeoff"]) & (t < j["land"]))
    assert len(air) >= 5
    y = p[:, r, 1] - b.record.keypoints[r, 1]
    # free fall: the second difference of the height is -g / FPS^2 between flight frames
    inner = air[1:-1]
    acc = (y[inner + 1] - 2 * y[inner] + y[inner - 1]) * FPS ** 2
    assert acc == pytest.approx(np.full(len(inner), -GRAVITY), abs=0.05)
    # the top of the flight is the stated rise, at the time v0 / g after take-off
    assert y.max() == pytest.approx(JUMP_HEIGHT * H, abs=GRAVITY / FPS ** 2)
    assert t[np.argmax(y)] == pytest.approx(j["takeoff"] + np.sqrt(2 * JUMP_HEIGHT * H / GRAVITY), abs=1 / FPS)
    # the legs (hips, knees, ankles, toes) are above where they stood at rest for the whole flight
    legs = [k for k, role in enumerate(b.record.bone_roles) if role.split("/")[-1] in ("thigh", "shin", "foot", "toe")]
    assert len(legs) == 8
    lift = p[air][:, legs, 1] - b.record.keypoints[None, legs, 1]
    assert lift.min() > 0.0
    # it lands: back at the rest height at the end of a 60-frame clip, and it never left its spot sideways
    assert abs(y[-1]) < 1e-4 and np.abs(p[:, r, [0, 2]] - p[0, r, [0, 2]]).max() < 1e-5


def test_turn_walks_along_a_heading_that_turns_by_the_stated_angle(built):
    b, clips = built
    q, p = clips["turn"]
    r = _root(b)
    yaw = _yaw(q[:, r])
    assert abs(yaw[-1] - yaw[0]) == pytest.approx(TURN_ANGLE, abs=1e-3)
    v = np.diff(p[:, r], axis=0)
    # after the ramp the root moves along its own heading (sin yaw, 0, cos yaw) at the stated speed
    for i in range(RAMP_FRAMES + 1, FRAMES - 1):
        assert v[i] * FPS == pytest.approx(0.55 * _height(b) * 1.2 * np.array([np.sin(yaw[i]), 0, np.cos(yaw[i])]),
                                           abs=2e-3)


def test_other_kinds_keep_their_clips_and_the_default_set_is_unchanged():
    spec = plan_zoo(12, seed=3, categories=["quadruped", "fish"])[0]
    from mimicbench.datagen.zoo.build import build_skeleton

    skel, _ = build_skeleton(spec)
    assert clip_list(spec.category, skel, 4, "dynamic") == clip_list(spec.category, skel, 4)
    hum = next(s for s in SPECS if s.category == "apparel")
    skel, _ = build_skeleton(hum)
    assert clip_names("apparel", skel) == ["walk", "idle", "random_poses", "run"]
    with pytest.raises(ValueError, match="clip_set: expected one of"):
        clip_names("apparel", skel, "spinny")


def test_zoo_records_a_non_default_clip_set_and_only_then(tmp_path):
    import json

    build_zoo(tmp_path / "d", 2, seed=1, categories=["apparel"], clips_per_character=1, progress=False)
    build_zoo(tmp_path / "y", 2, seed=1, categories=["apparel"], clips_per_character=1, progress=False,
              clip_set="dynamic")
    configs = {k: json.loads((tmp_path / k / "manifest.json").read_text())["configs"]["characters"]
               for k in ("d", "y")}
    assert "clip_set" not in json.dumps(configs["d"])
    assert '"clip_set": "dynamic"' in json.dumps(configs["y"])
    with pytest.raises(ValueError, match="clip_set"):
        build_zoo(tmp_path / "n", 2, seed=1, categories=["apparel"], clip_set="nope", progress=False)
    assert not (tmp_path / "n").exists()
