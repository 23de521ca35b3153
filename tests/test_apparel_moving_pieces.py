"""Issue 33, simulation version 13: body pieces that Bullet's contacts see moving.

Up to version 12 every body piece was a static body placed anew at its bone's pose each step:
Bullet took it as standing still, so a contact spring's damping (every chain link below its root
touches the body through one since version 12) acted on the link's speed in the world instead of
its speed against the limb. A link carried along by a limb moving at v sank 2 v / w deeper into it
than at rest (w the spring's frequency), and a link moving with the limb was stopped in the world
within a step: on the seed-711 dynamic zoo an arm sweeping round in a spin struck the cape it
carried (16 of 40 spins above 3x their kinematic peak, worst frames up to 2.4 % of apparel
vertices inside the body). Now each piece starts a step where the last one ended and carries the speed
that takes it to its pose (:attr:`mimicbench.datagen.apparel.params.SimParams.piece_velocity`).
"""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.apparel.params import ApparelParams, SimParams
from mimicbench.datagen.apparel.world import ApparelWorld, piece_velocities

FPS, SUBSTEPS = 30.0, 8


def _pressed_strand(piece_velocity: bool, speed: float, frames: int = 60, still: int = 20,
                    collision_mask: int = 0b01) -> np.ndarray:
    """A hair strand (4 links with the 8 x 1 cm hulls of :data:`tests.test_apparel_physics.STRIP`, the
    zoo's hair parameters: rigid root contacts, a contact spring below) hanging from bone 0 at 1 m,
    and a box 12 x 6 x 4 cm whose back face is 5 mm into the strand's third link: it pushes the
    strand back, and the strand's springs press it against the box. The whole scene (anchor and
    box) stands for ``still`` frames, then moves along -Z (toward the strand) at ``speed`` m/s.
    ``collision_mask``: the strand's (0b01 collides with the body; 0 is ``collide_body`` false).

    Returns the link heads relative to the anchor (F, 4, 3), metres."""
    from mimicbench.datagen.apparel.body_shapes import body_pieces
    from mimicbench.datagen.apparel.chain_spec import ChainSpec, JointSpec, LinkSpec
    from mimicbench.datagen.apparel.simulate import simulate_clip
    from mimicbench.geometry.kinematics import rest_transforms
    from tests.test_apparel_physics import STRIP

    hair = ApparelParams().for_kind("hair")
    heads = np.array([[0.0, 1.0 - 0.08 * i, 0.0] for i in range(4)])
    box = np.array([0.0, 0.80, 0.015])
    keypoints = np.concatenate([[[0.0, 1.0, 0.0]], [box], heads])
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.array([0.06, 0.03, 0.02])
    pieces = body_pieces(corners + box, keypoints, np.ones(8, int), np.array([False, True] + [False] * 4))
    links = tuple(LinkSpec(2 + i, heads[i], np.array([0.0, -1.0, 0.0]), 0.08, 0.01, hair.link_mass, hull=STRIP,
                           axial_share=1.0,
                           contact_frequency=hair.root_contact_frequency if i == 0 else hair.contact_frequency)
                  for i in range(4))
    joint = JointSpec(hair.swing_limit, hair.twist_limit, hair.stiffness, hair.damping, 0.2)
    chain = ChainSpec("strand", "hair", 0, links, (-1, 0, 1, 2), (joint,) * 4, collision_mask=collision_mask)
    clip = np.repeat(rest_transforms(keypoints).astype(np.float64)[None], frames, axis=0)
    clip[:, :, 6] -= speed * np.clip(np.arange(frames) - still, 0, None)[:, None] / FPS
    with ApparelWorld(keypoints, pieces, [chain], SimParams(piece_velocity=piece_velocity),
                      1.0 / (FPS * SUBSTEPS)) as world:
        out = simulate_clip(world, clip, SUBSTEPS, 0).transforms.astype(np.float64)
    return out[:, 2:, 4:] - out[:, :1, 4:]


def test_a_strand_pressed_on_a_moving_limb_lies_as_on_a_still_one():
    # Galilean invariance: a scene carried at a constant speed behaves as the scene at rest. The
    # strand's third link lies pressed on the box by its springs with some force N. Through a
    # critically damped contact spring (stiffness k = m w^2, damping c = 2 m w) it sinks x = N / k
    # into a box at rest; on a box moving toward it at v that Bullet takes as standing still, the
    # link moves away from it at v, the damper takes c v off the spring's push, and
    # x = (N + c v) / k: 2 v / w deeper, 6.7 mm at v = 0.5 m/s and the zoo's hair w = 150 rad/s
    # (simulation version 12). With the box's speed seen, the strand lies where it lay at rest:
    # the bound is a sixth of that 2 v / w (the anchor's own constraint lags it by about 0.5 mm)
    w, v = ApparelParams().for_kind("hair").contact_frequency, 0.5
    assert w == 150.0
    for piece_velocity in (True, False):
        heads = _pressed_strand(piece_velocity, v)
        deeper = heads[-1, 2:, 2] - heads[19, 2:, 2]  # (2,) the lower links' shift along the motion, m
        assert np.abs(heads[19, 2:, 2]).min() > 0.005  # the box pushed the strand back
        if piece_velocity:
            assert np.abs(deeper).max() < 2 * v / w / 6, deeper
        else:  # the scene shows version 12's fault, and its size is the derived 2 v / w
            assert deeper[0] == pytest.approx(2 * v / w, rel=0.1), deeper


def test_a_chain_that_does_not_collide_with_the_body_passes_through_it():
    # collide_body false gives a chain the mask 0 (chains.build_chains). The body pieces' mask holds
    # the chains' group, and pybullet's default filter lets a pair collide when either one's group is
    # in the other's mask, so the strand was pushed back as if it collided (simulation version 13);
    # the world takes the filter where each must be in the other's mask. The box starts 5 mm into
    # the strand's third link and stands still: with collisions the strand is pushed back past
    # that 5 mm, without them it hangs straight down (its links' Z within a millimetre of the anchor)
    pushed = _pressed_strand(True, 0.0, frames=30, still=30)
    assert np.abs(pushed[-1, 2:, 2]).min() > 0.005
    free = _pressed_strand(True, 0.0, frames=30, still=30, collision_mask=0)
    assert np.abs(free[:, :, 2]).max() < 1e-3, free[-1]


def test_piece_velocities_carry_a_piece_to_its_next_pose():
    # a piece turning about Y at 3 rad/s with its head moving along +X at 0.5 m/s: over a step dt the
    # velocities take it from one placement to the next (the turn's rotation vector / dt, the
    # head's shift / dt), with gravity's dt g added upward (Bullet adds -g dt before the contacts)
    dt, g = 1 / 240, 9.8
    angle = np.array([0.2, 0.2 + 3 * dt])
    placements = np.zeros((2, 7))
    placements[:, 0] = 0.5 * dt * np.arange(2)
    placements[:, 4] = np.sin(angle / 2)  # (x, y, z, w) about Y
    placements[:, 6] = np.cos(angle / 2)
    speeds = piece_velocities(placements[1], placements[0], dt, g)
    np.testing.assert_allclose(speeds[0], [0.5, g * dt, 0.0], atol=1e-9)
    np.testing.assert_allclose(speeds[1], [0.0, 3.0, 0.0], atol=1e-9)
    before = np.full(7, np.nan)  # no placement before: no speed but gravity's
    np.testing.assert_allclose(piece_velocities(placements[1], before, dt, g), [[0.0, g * dt, 0.0], [0.0] * 3],
                               atol=1e-12)
