"""Clip generators per kind of character: gaits, flaps, swims, slithers, idles, random poses.

Each generator has the signature ``gen(skel, rng, num_frames) -> (rotvec (F, K, 3), root_offset (F, 3))``
(see :mod:`mimicbench.datagen.zoo.motions`). Axes are in the rest frame: X is the character's left, Y up,
Z forward. Legs are found from the hidden roles; phase offsets make real gaits (a quadruped's
lateral-sequence walk, an insect's alternating tripod, a biped's alternating legs).
"""
from __future__ import annotations

import re

import numpy as np

from mimicbench.datagen.zoo.motions import FPS, RAMP_FRAMES, random_poses
from mimicbench.datagen.zoo.skeleton import Skeleton

X, Y, Z = np.eye(3)


def _t(num_frames: int) -> np.ndarray:
    return np.arange(num_frames) / FPS


def _idx(skel: Skeleton, pattern: str) -> list[int]:
    rx = re.compile(pattern)
    return [k for k, r in enumerate(skel.roles) if rx.fullmatch(r)]


def _legs(skel: Skeleton) -> dict[str, list[int]]:
    """Leg chains by key ``side/part[/i]`` (joint indices top to bottom)."""
    legs: dict[str, list[int]] = {}
    for k, r in enumerate(skel.roles):
        m = re.fullmatch(r"(left|right)/(front_leg|hind_leg|leg)(/\d+)?/(\d+)", r)
        if m:
            legs.setdefault(f"{m[1]}/{m[2]}{m[3] or ''}", []).append(k)
    return legs


def _side(key: str) -> float:
    return 1.0 if key.startswith("left") else -1.0


def _height(skel: Skeleton) -> float:
    return float(np.ptp(np.concatenate([skel.heads, skel.tails])[:, 1])) or 1.0


def _length(skel: Skeleton) -> float:
    return float(np.ptp(np.concatenate([skel.heads, skel.tails])[:, 2])) or 1.0


def _wave(skel: Skeleton, rv, t, joints: list[int], freq: float, total: float, axis=Y, waves: float = 1.2,
          grow: bool = True) -> None:
    """Add a travelling wave of local rotations about ``axis`` along ``joints`` (head to tail order)."""
    n = len(joints)
    if not n:
        return
    for i, k in enumerate(joints):
        amp = total / n * ((0.4 + 1.2 * i / max(1, n - 1)) if grow else 1.0)
        amp = min(amp, skel.limits[k])
        rv[:, k] += axis * (amp * np.sin(2 * np.pi * (freq * t - waves * i / n)))[:, None]


def _apparel_sway(skel: Skeleton, rv, t, freq: float, amp: float) -> None:
    for k in np.nonzero(skel.apparel)[0]:
        seg = int(skel.roles[k].split("/")[-1])
        rv[:, k] += X * (amp * np.sin(2 * np.pi * freq * t - 0.7 * seg))[:, None]
        rv[:, k] += Z * (0.5 * amp * np.sin(2 * np.pi * 0.5 * freq * t - 0.5 * seg + k))[:, None]


def _tails(skel, rv, t, freq, amp):
    _wave(skel, rv, t, _idx(skel, r"tail/\d+"), freq, amp, Y)


def _arms_down(skel: Skeleton, rv, amount: float) -> None:
    """Lower the arms towards the body about Z by up to ``amount`` (less for an A-pose)."""
    for side, s in (("left", 1.0), ("right", -1.0)):
        k = skel.index(f"{side}/upper_arm")
        d = skel.tails[k] - skel.heads[k]
        tilt = np.arcsin(-d[1] / np.linalg.norm(d))
        rv[:, k] += -s * Z * max(0.0, amount - tilt)


def humanoid_walk(skel: Skeleton, rng, num_frames: int, speed: float = 1.0):
    t = _t(num_frames)
    H = _height(skel)
    f = 0.9 * speed * float(rng.uniform(0.9, 1.1))
    ph = 2 * np.pi * f * t
    rv = np.zeros((num_frames, skel.num_joints, 3))
    for side, s, off in (("left", 1.0, 0.0), ("right", -1.0, np.pi)):
        a = ph + off
        rv[:, skel.index(f"{side}/thigh")] += X * (-0.45 * speed * np.sin(a))[:, None]
        rv[:, skel.index(f"{side}/shin")] += X * (0.35 * speed * (1 - np.cos(a + 0.8)))[:, None]
        rv[:, skel.index(f"{side}/foot")] += X * (-0.15 * np.sin(a + 0.5))[:, None]
        rv[:, skel.index(f"{side}/upper_arm")] += -s * Y * (-0.35 * speed * np.sin(a + np.pi))[:, None]
        rv[:, skel.index(f"{side}/forearm")] += -s * Y * 0.3
    _arms_down(skel, rv, 1.1)
    for k in _idx(skel, r"spine/\d+"):
        rv[:, k] += Y * (0.05 * np.sin(ph))[:, None] + X * 0.02 * speed
    rv[:, skel.index("head")] += X * (0.04 * np.sin(2 * ph))[:, None]
    _apparel_sway(skel, rv, t, 2 * f, 0.12 * speed)
    root = np.stack([0 * t, 0.012 * H * (1 - np.cos(2 * ph)) / 2, 0.55 * H * speed * t], 1)
    return rv, root


def humanoid_run(skel, rng, num_frames):
    return humanoid_walk(skel, rng, num_frames, speed=1.6)


def humanoid_idle(skel: Skeleton, rng, num_frames: int):
    t = _t(num_frames)
    br = np.sin(2 * np.pi * 0.35 * t)
    rv = np.zeros((num_frames, skel.num_joints, 3))
    for k in _idx(skel, r"spine/\d+"):
        rv[:, k] += X * (-0.03 * br)[:, None]
    rv[:, skel.index("head")] += Y * (0.25 * np.sin(2 * np.pi * 0.3 * t))[:, None]
    _arms_down(skel, rv, 1.0)
    for side, s in (("left", 1.0), ("right", -1.0)):
        rv[:, skel.index(f"{side}/shoulder")] += -s * Z * (0.04 * br)[:, None]
        rv[:, skel.index(f"{side}/forearm")] += -s * Y * 0.2
    _apparel_sway(skel, rv, t, 0.6, 0.08)
    return rv, np.zeros((num_frames, 3))


def legged_walk(skel: Skeleton, rng, num_frames: int, phases: dict[str, float] | None = None, freq: float = 1.2,
                speed: float = 1.0):
    """A gait for any legged animal: each leg swings and lifts with its own phase."""
    t = _t(num_frames)
    legs = _legs(skel)
    rv = np.zeros((num_frames, skel.num_joints, 3))
    keys = sorted(legs)
    for key in keys:
        chain = legs[key]
        s = _side(key)
        if phases is None:
            phase = _default_phase(key)
        else:
            phase = phases.get(key, 0.0)
        a = 2 * np.pi * (freq * t + phase)
        top, end = skel.heads[chain[0]], skel.tails[chain[-1]]
        d = end - top
        lateral = abs(d[0]) > abs(d[1])
        lift = np.maximum(0.0, np.sin(a + np.pi / 2))
        if lateral:  # splayed legs (insects, lizards): sweep about Y, lift about Z
            rv[:, chain[0]] += Y * (s * 0.35 * np.sin(a))[:, None] + Z * (s * 0.3 * lift)[:, None]
            if len(chain) > 2:
                rv[:, chain[2]] += Z * (-s * 0.2 * lift)[:, None]
        else:  # legs under the body: swing about X, bend the next joint
            rv[:, chain[0]] += X * (-0.4 * np.sin(a))[:, None]
            if len(chain) > 1:
                rv[:, chain[1]] += X * (0.5 * lift * (1 if "hind" in key or "front" not in key else -1))[:, None]
    _tails(skel, rv, t, freq, 0.5)
    spine = _idx(skel, r"spine/\d+")
    for k in spine:
        rv[:, k] += Y * (0.04 * np.sin(2 * np.pi * freq * t))[:, None]
    H = _height(skel)
    L = max(_length(skel), H)
    root = np.stack([0 * t, 0.01 * H * (1 - np.cos(4 * np.pi * freq * t)) / 2, 0.5 * L * speed * freq * t], 1)
    return rv, root


def _default_phase(key: str) -> float:
    """Leg phases (fractions of a cycle): lateral-sequence walk, alternating tripod, biped."""
    side = 0 if key.startswith("left") else 1
    if "front_leg" in key:
        return 0.25 + 0.5 * side
    if "hind_leg" in key:
        return 0.5 * side
    m = re.search(r"leg/(\d+)", key)
    if m:  # insects and spiders: neighbouring legs alternate, the two sides are opposite
        return 0.5 * ((int(m[1]) + side) % 2)
    return 0.5 * side


def trot(skel, rng, num_frames):
    phases = {"left/front_leg": 0.0, "right/hind_leg": 0.0, "right/front_leg": 0.5, "left/hind_leg": 0.5}
    return legged_walk(skel, rng, num_frames, phases, freq=2.0, speed=1.5)


def animal_idle(skel: Skeleton, rng, num_frames: int):
    t = _t(num_frames)
    rv = np.zeros((num_frames, skel.num_joints, 3))
    br = np.sin(2 * np.pi * 0.4 * t)
    for k in _idx(skel, r"(spine|abdomen)/\d+"):
        rv[:, k] += X * (0.02 * br)[:, None]
    necks = _idx(skel, r"neck(/\d+)?")
    for k in necks:
        rv[:, k] += X * (0.3 / len(necks) * np.sin(2 * np.pi * 0.5 * t))[:, None]
    for k in _idx(skel, r"head"):
        rv[:, k] += Y * (0.25 * np.sin(2 * np.pi * 0.3 * t + 0.5))[:, None]
    for k in _idx(skel, r"jaw|beak"):
        rv[:, k] += X * (0.15 * (1 - np.cos(2 * np.pi * 1.0 * t)) / 2)[:, None]
    for k in _idx(skel, r"(left|right)/(ear|antenna/\d+|fang)"):
        rv[:, k] += Z * (0.25 * np.sin(2 * np.pi * 1.3 * t + k))[:, None]
    for k in _idx(skel, r"(left|right)/wing/1"):
        s = 1.0 if skel.roles[k].startswith("left") else -1.0
        rv[:, k] += Y * s * 0.9 + Z * (-s * 0.25)
    _tails(skel, rv, t, 0.8, 0.35)
    return rv, np.zeros((num_frames, 3))


def flap(skel: Skeleton, rng, num_frames: int):
    t = _t(num_frames)
    f = float(rng.uniform(2.5, 3.5))
    rv = np.zeros((num_frames, skel.num_joints, 3))
    for k in _idx(skel, r"(left|right)/wing/\d+"):
        s = 1.0 if skel.roles[k].startswith("left") else -1.0
        i = int(skel.roles[k].split("/")[-1])
        amp = (0.8, 0.35, 0.3, 0.25)[min(i, 4) - 1]
        rv[:, k] += Z * (s * amp * np.sin(2 * np.pi * f * t - 0.6 * (i - 1)))[:, None]
    for k in _idx(skel, r"(left|right)/leg/1"):
        rv[:, k] += X * 0.6  # tuck the legs back
    _tails(skel, rv, t, f / 2, 0.2)
    H = _height(skel)
    root = np.stack([0 * t, 0.05 * H * (1 - np.cos(2 * np.pi * f * t)) / 2 + 0.3 * H * t, 1.0 * H * t], 1)
    return rv, root


def bird_walk(skel, rng, num_frames):
    return legged_walk(skel, rng, num_frames, freq=1.6)


def _body_chain(skel: Skeleton) -> list[int]:
    """Joints along the body from the front to the back (spine reversed, root, tail)."""
    spine = _idx(skel, r"spine/\d+")
    if skel.roles[0] in ("root",) and spine and skel.heads[spine[-1], 2] < skel.heads[0, 2]:
        return [0] + spine  # a snake's spine runs backwards from the root
    return list(reversed(spine)) + [0] + _idx(skel, r"tail/\d+") + _idx(skel, r"tail_fin")


def swim(skel: Skeleton, rng, num_frames: int):
    t = _t(num_frames)
    f = float(rng.uniform(1.2, 2.0))
    rv = np.zeros((num_frames, skel.num_joints, 3))
    _wave(skel, rv, t, _body_chain(skel), f, 0.9, Y, waves=1.0)
    for k in _idx(skel, r"(left|right)/(fin|pelvic_fin)"):
        s = 1.0 if skel.roles[k].startswith("left") else -1.0
        rv[:, k] += Z * (s * 0.4 * np.sin(2 * np.pi * 2 * f * t))[:, None]
    L = _length(skel)
    return rv, np.stack([0 * t, 0 * t, 0.6 * L * t], 1)


def slither(skel: Skeleton, rng, num_frames: int):
    t = _t(num_frames)
    f = float(rng.uniform(0.8, 1.2))
    rv = np.zeros((num_frames, skel.num_joints, 3))
    _wave(skel, rv, t, _body_chain(skel), f, 3.0, Y, waves=1.5, grow=False)
    L = _length(skel)
    return rv, np.stack([0 * t, 0 * t, 0.25 * L * t], 1)


def random_clip(skel: Skeleton, rng, num_frames: int):
    return random_poses(skel, rng, num_frames), np.zeros((num_frames, 3))


CLIP_SETS = ("default", "dynamic")
DYNAMIC_CLIPS = ["spin", "stop", "jump", "turn"]


def clip_names(category: str, skel: Skeleton, clip_set: str = "default") -> list[str]:
    """The clip generators suited to a character, in order of preference.

    ``clip_set="dynamic"`` puts the motions where apparel lags and swings (:data:`DYNAMIC_CLIPS`)
    first for humanoids and apparel characters; other kinds keep their default clips.
    """
    if clip_set not in CLIP_SETS:
        raise ValueError(f"clip_set: expected one of {list(CLIP_SETS)}, got {clip_set!r}")
    if clip_set == "dynamic" and category in ("humanoid", "apparel"):
        return DYNAMIC_CLIPS + ["walk", "idle", "random_poses", "run"]
    if category in ("humanoid", "apparel"):
        return ["walk", "idle", "random_poses", "run"]
    if category == "quadruped":
        return ["walk", "idle", "random_poses", "trot"]
    if category == "bird":
        return ["flap", "idle", "random_poses", "walk"]
    if category == "fish":
        return ["swim", "idle", "random_poses"]
    if category == "reptile":
        legged = bool(_legs(skel))
        return (["walk", "idle", "random_poses"] if legged else ["slither", "idle", "random_poses"])
    return ["walk", "idle", "random_poses"]


def generator(category: str, name: str):
    """The generator function of clip ``name`` for ``category`` (``random_poses_<i>`` too)."""
    if name.startswith("random_poses"):
        return random_clip
    human = category in ("humanoid", "apparel")
    table = {
        "walk": humanoid_walk if human else (bird_walk if category == "bird" else legged_walk),
        "run": humanoid_run, "idle": humanoid_idle if human else animal_idle, "trot": trot,
        "flap": flap, "swim": swim, "slither": slither,
        "spin": humanoid_spin, "stop": humanoid_stop, "jump": humanoid_jump, "turn": humanoid_turn,
    }
    return table[name]


# --- the "dynamic" clip set: motions where apparel lags and swings (opt-in, mimicbench.datagen.zoo.build.CLIP_SETS) ---

GRAVITY = 9.8  # m/s^2, the apparel stage's default gravity, so a jump's flight is the simulation's free fall
SPIN_ANGLE = 2 * np.pi  # a spin turns the root by one full turn (sign drawn per clip)
TURN_ANGLE = np.pi / 2  # a turn walks a quarter circle (sign drawn per clip)
JUMP_HEIGHT = 0.1  # a jump's rise of the root in flight, share of the skeleton's height
CROUCH_DEPTH = 0.06  # how far the hips sink before take-off and after landing, share of the height
STOP_FRAMES = 3  # a stop goes from walking speed to standing still in this many frames


def _start() -> float:
    """Seconds at which a dynamic motion starts: after the blend-in ramp, so its angles and offsets are exact."""
    return RAMP_FRAMES / FPS


def _smooth(x: np.ndarray) -> np.ndarray:
    """Smootherstep of ``x`` clipped to [0, 1] (zero speed and acceleration at both ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)


def _root(skel: Skeleton) -> int:
    return int(np.flatnonzero(skel.parents < 0)[0])


def _yaw_walk(skel: Skeleton, rv, yaw: np.ndarray, speed: np.ndarray, bob: np.ndarray) -> np.ndarray:
    """Turn the root by ``yaw`` (F,) radians about Y and walk it along its heading at ``speed`` (F,) m/s.

    The position integrates the heading (sin yaw, 0, cos yaw) frame by frame (explicit Euler at
    ``1 / FPS``), so a zero speed leaves the root exactly where it is. Returns the root offset (F, 3).
    """
    rv[:, _root(skel)] += Y * yaw[:, None]
    step = speed / FPS
    heading = np.stack([np.sin(yaw), 0 * yaw, np.cos(yaw)], 1)
    pos = np.concatenate([np.zeros((1, 3)), np.cumsum(heading[:-1] * step[:-1, None], axis=0)])
    pos[:, 1] = bob
    return pos


def humanoid_spin(skel: Skeleton, rng, num_frames: int):
    """A spin on the spot: the root turns by ``SPIN_ANGLE`` (either way) about Y, arms out, then stops.

    The turn runs from the end of the blend-in ramp to 80% of the clip with a smootherstep (peak
    speed 1.875x the mean), then holds; apparel flies out and swings on after the stop.
    """
    t = _t(num_frames)
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    t0, t1 = _start(), max(_start() + 2 / FPS, 0.8 * num_frames / FPS)
    rv = np.zeros((num_frames, skel.num_joints, 3))
    _arms_down(skel, rv, 0.5)
    _apparel_sway(skel, rv, t, 0.8, 0.05)
    yaw = sign * SPIN_ANGLE * _smooth((t - t0) / (t1 - t0))
    root = _yaw_walk(skel, rv, yaw, 0 * t, 0 * t)
    return rv, root


def humanoid_turn(skel: Skeleton, rng, num_frames: int):
    """A walk that turns by ``TURN_ANGLE`` (either way): the heading follows the root's yaw.

    The yaw rises with a smootherstep from the end of the ramp to 80% of the clip; the limbs walk
    as :func:`humanoid_walk` at speed 1.2 throughout.
    """
    t = _t(num_frames)
    H = _height(skel)
    rv, _ = humanoid_walk(skel, rng, num_frames, speed=1.2)
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    t0, t1 = _start(), max(_start() + 2 / FPS, 0.8 * num_frames / FPS)
    yaw = sign * TURN_ANGLE * _smooth((t - t0) / (t1 - t0))
    speed = np.full(num_frames, 0.55 * H * 1.2)
    return rv, _yaw_walk(skel, rv, yaw, speed, 0 * t)


def humanoid_stop(skel: Skeleton, rng, num_frames: int):
    """A brisk walk (speed 1.4) that stops dead: speed and limb motion fall to zero in ``STOP_FRAMES`` frames.

    The stop begins at frame ``max(RAMP_FRAMES + 1, round(0.55 F))``; from frame ``stop + STOP_FRAMES``
    on the character stands in its rest pose and its root does not move, while apparel swings on.
    """
    rv, _ = humanoid_walk(skel, rng, num_frames, speed=1.4)
    H = _height(skel)
    stop = stop_frame(num_frames)
    i = np.arange(num_frames)
    gate = 1.0 - np.clip((i - stop) / STOP_FRAMES, 0.0, 1.0)
    rv *= gate[:, None, None]
    speed = 0.55 * H * 1.4 * gate
    return rv, _yaw_walk(skel, rv, 0 * speed, speed, 0 * speed)


def stop_frame(num_frames: int) -> int:
    """The frame at which :func:`humanoid_stop` begins to stop."""
    return max(RAMP_FRAMES + 1, int(round(0.55 * num_frames)))


def jump_timing(height: float) -> dict[str, float]:
    """Phase times (s) of :func:`humanoid_jump` for a skeleton ``height`` (m) tall.

    Keys: ``crouch`` (start of the crouch), ``push`` (start of the push-off), ``takeoff``, ``land``,
    ``absorbed`` (lowest after landing), ``up`` (standing again); ``v0`` (take-off speed, m/s),
    ``rise`` (m, the root's height above rest at the top) and ``depth`` (m, the crouch).
    Flight is free fall at ``GRAVITY``: it lasts ``2 v0 / g`` with ``v0 = sqrt(2 g rise)``. The push-off
    and the landing are uniform accelerations over the crouch depth (each lasts ``2 depth / v0``).
    """
    rise, depth = JUMP_HEIGHT * height, CROUCH_DEPTH * height
    v0 = float(np.sqrt(2 * GRAVITY * rise))
    crouch = _start()
    push = crouch + 0.3
    takeoff = push + 2 * depth / v0
    land = takeoff + 2 * v0 / GRAVITY
    absorbed = land + 2 * depth / v0
    return {"crouch": crouch, "push": push, "takeoff": takeoff, "land": land, "absorbed": absorbed,
            "up": absorbed + 0.3, "v0": v0, "rise": rise, "depth": depth}


def _jump_height(t: np.ndarray, j: dict[str, float]) -> np.ndarray:
    """Root height above rest (F,) m over a jump (negative while crouched)."""
    d, v0 = j["depth"], j["v0"]
    acc = v0 * v0 / (2 * d)
    y = np.zeros_like(t)
    s = (t >= j["crouch"]) & (t < j["push"])
    y[s] = -d * _smooth((t[s] - j["crouch"]) / (j["push"] - j["crouch"]))
    s = (t >= j["push"]) & (t < j["takeoff"])
    y[s] = -d + 0.5 * acc * (t[s] - j["push"]) ** 2
    s = (t >= j["takeoff"]) & (t < j["land"])
    tau = t[s] - j["takeoff"]
    y[s] = v0 * tau - 0.5 * GRAVITY * tau ** 2
    s = (t >= j["land"]) & (t < j["absorbed"])
    tau = t[s] - j["land"]
    y[s] = -v0 * tau + 0.5 * acc * tau ** 2
    s = t >= j["absorbed"]
    y[s] = -d * (1 - _smooth((t[s] - j["absorbed"]) / (j["up"] - j["absorbed"])))
    return y


def humanoid_jump(skel: Skeleton, rng, num_frames: int):
    """A jump on the spot: crouch, push off, free flight at ``GRAVITY``, land into a crouch, stand up.

    Phases are :func:`jump_timing`'s (absolute seconds: a clip shorter than about 1.5 s ends mid-jump).
    While crouched, each thigh pitches forward by ``a`` and its shin back by ``2a`` (the foot by ``a``),
    with ``cos a = 1 - depth / leg``, so a straight vertical leg keeps its foot where it stood; in
    flight the legs are straight and the arms swing up (0.8 rad at the top) and down again.
    """
    t = _t(num_frames)
    H = _height(skel)
    j = jump_timing(H)
    y = _jump_height(t, j)
    rv = np.zeros((num_frames, skel.num_joints, 3))
    _arms_down(skel, rv, 1.0)
    sink = np.maximum(0.0, -y)
    lift = np.sin(np.pi * np.clip((t - j["push"]) / (j["absorbed"] - j["push"]), 0.0, 1.0))  # arms up in flight
    for side, s in (("left", 1.0), ("right", -1.0)):
        thigh, shin, foot = (skel.index(f"{side}/{p}") for p in ("thigh", "shin", "foot"))
        leg = float(np.linalg.norm(skel.heads[foot] - skel.heads[thigh]))
        a = np.arccos(np.clip(1 - sink / leg, -1.0, 1.0))
        rv[:, thigh] += X * (-a)[:, None]
        rv[:, shin] += X * (2 * a)[:, None]
        rv[:, foot] += X * (-a)[:, None]
        rv[:, skel.index(f"{side}/upper_arm")] += s * Z * (0.8 * lift)[:, None]
    _apparel_sway(skel, rv, t, 0.8, 0.04)
    return rv, np.stack([0 * t, y, 0 * t], 1)
