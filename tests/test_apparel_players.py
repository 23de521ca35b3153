"""The file-physics world as MMD's players run it (datagen/apparel/file_physics.py with the
``SimParams.file_*`` settings): a pendulum at the chosen step rate against its analytic period,
the reset that zeroes velocities, a warm-up that leaves a resting model at rest, a clip that starts
far from the origin not dragged there, and chains that never sleep."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ellipk

from mimicbench.datagen.apparel.file_physics import FileWorld
from mimicbench.datagen.apparel.params import SimParams
from mimicbench.datagen.apparel.simulate import simulate_clip
from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.schemas.joint import JointRecord
from mimicbench.schemas.rigid_body import RigidBodyRecord

PIVOT = np.array([0.0, 1.0, 0.0])
ARM = 0.5  # metres from the pivot to the bob's centre
RADIUS = 0.05  # the bob, a solid sphere
FREE = (np.ones(3), -np.ones(3))  # lower above upper: a free axis (Bullet's convention)
G = 9.8
PARAMS = SimParams()


def _body(i, shape, size, pos, mode, group=0, mask=0xFFFF, bone=0, damping=0.0):
    return RigidBodyRecord("toy", i, f"b{i}", "", bone, shape, np.float32(size), np.float32(pos),
                           np.float32([1, 0, 0, 0]), 1.0, damping, damping, 0.0, 0.5, group, mask, mode)


def _pendulum(bob_offset, damping=0.0):
    """A static sphere at the pivot (bone 0) and a dynamic sphere bob (bone 1) at ``bob_offset``
    from it on a free spherical joint; no spring, the given damping."""
    z = np.zeros(3, np.float32)
    bodies = [_body(0, "sphere", [0.02, 0, 0], PIVOT, "static", group=3),
              _body(1, "sphere", [RADIUS, 0, 0], PIVOT + bob_offset, "dynamic", group=1, mask=0xFFFF & ~(1 << 3),
                    bone=1, damping=damping)]
    joint = JointRecord("toy", 0, "j", "", "spring_6dof", 0, 1, np.float32(PIVOT), np.float32([1, 0, 0, 0]), z, z,
                        np.float32(FREE[0]), np.float32(FREE[1]), z, z)
    return bodies, [joint], np.array([PIVOT, PIVOT + bob_offset])


def _world(bodies, joints, keypoints, dt, **kw):
    return FileWorld(bodies, joints, keypoints, np.array([-1, 0]), dt, PARAMS.file_solver_iterations, 0.08,
                     apparel=np.array([False, True]), erp=PARAMS.file_erp, sleeping=PARAMS.file_sleeping, **kw)


def _bottom_crossings(times, x):
    """Times (linearly interpolated) at which the bob's x goes from positive to negative."""
    i = np.nonzero((x[:-1] > 0) & (x[1:] <= 0))[0]
    return times[i] + (times[i + 1] - times[i]) * x[i] / (x[i] - x[i + 1])


def test_pendulum_at_the_chosen_step_rate_keeps_its_analytic_period():
    # released 45 degrees from the vertical (its rest, so it swings at most 90 degrees from rest, well
    # inside the free joint's 3.1 rad cone): a physical pendulum's period is 4 sqrt(I / (m g L)) K(k),
    # k = sin(22.5 degrees), I = m L^2 + 2/5 m r^2 about the pivot (K: the complete elliptic integral)
    rate = PARAMS.file_step_rate
    start = np.pi / 4
    bodies, joints, keypoints = _pendulum(ARM * np.array([np.sin(start), -np.cos(start), 0.0]))
    inertia = ARM ** 2 + 0.4 * RADIUS ** 2
    period = 4.0 * np.sqrt(inertia / (G * ARM)) * ellipk(np.sin(start / 2) ** 2)  # scipy's K takes m = k^2
    rest = rest_transforms(keypoints).astype(np.float64)
    steps = int(4 * period * rate)
    xs = np.zeros(steps)
    with _world(bodies, joints, keypoints, 1.0 / rate, gravity=G) as world:
        for s in range(steps):
            world.set_body_pose(rest)
            world.step()
            xs[s] = world.body_poses()[0][1][0] - PIVOT[0]
    crossings = _bottom_crossings(np.arange(1, steps + 1) / rate, xs)
    assert len(crossings) >= 3
    measured = np.diff(crossings).mean()
    assert measured == pytest.approx(period, rel=1e-3), (measured, period)


def test_reset_zeroes_every_velocity_and_puts_the_chain_at_rest_on_its_anchor():
    bodies, joints, keypoints = _pendulum(np.array([ARM, 0.0, 0.0]))
    rest = rest_transforms(keypoints).astype(np.float64)
    with _world(bodies, joints, keypoints, 1.0 / PARAMS.file_step_rate, gravity=G) as world:
        for _ in range(40):  # swinging down fast
            world.set_body_pose(rest)
            world.step()
        assert world.read()[1] > 1.0
        moved = rest.copy()
        moved[:, 4:] += [2.0, 0.0, -3.0]  # the body somewhere else
        world.reset(moved)
        state, speed = world.read()
        assert speed == 0.0
        # one step from rest under gravity: the bob has fallen at most g dt^2, still at its rest offset
        np.testing.assert_allclose(state[0][0], moved[1, 4:], atol=2 * G / PARAMS.file_step_rate ** 2)


def test_warm_up_leaves_a_resting_model_at_rest_where_its_clip_starts():
    # a bob hanging straight down (its rest is its equilibrium) and a still clip 30 m from the origin,
    # turned half round: with the players' reset and warm-up the bob hangs still below the pivot from
    # frame 0; blended from the rest pose at the origin, it is dragged there and swings
    bodies, joints, keypoints = _pendulum(np.array([0.0, -ARM, 0.0]), damping=0.5)
    clip = np.repeat(rest_transforms(keypoints)[None], 20, axis=0).astype(np.float64)
    turn = np.array([np.cos(np.pi / 2), 0.0, np.sin(np.pi / 2), 0.0])  # half a turn about Y
    clip[:, :, :4] = turn
    clip[:, 0, 4:] = PIVOT + [30.0, 0.0, 0.0]
    clip[:, 1, 4:] = PIVOT + [30.0, -ARM, 0.0]
    rate = PARAMS.file_step_rate
    substeps = int(round(rate / 30))

    def run(warmup):
        with _world(bodies, joints, keypoints, 1.0 / (30 * substeps), gravity=G, max_speed=1e6) as world:
            return simulate_clip(world, clip, substeps, 30, warmup=warmup).transforms

    warm = run(True)
    np.testing.assert_allclose(warm[:, 1, 4:], clip[:, 1, 4:], atol=1e-4)
    dragged = run(False)
    assert np.abs(dragged[:, 1, 4:] - clip[:, 1, 4:]).max() > 0.01


def test_chains_never_sleep():
    # a hanging bob left still for 3 s (longer than Bullet's 2 s deactivation time), then its pivot
    # moves 0.2 m along X in a tenth of a second: the bob follows
    bodies, joints, keypoints = _pendulum(np.array([0.0, -ARM, 0.0]), damping=0.5)
    rest = rest_transforms(keypoints).astype(np.float64)
    rate = PARAMS.file_step_rate
    assert not PARAMS.file_sleeping
    with _world(bodies, joints, keypoints, 1.0 / rate, gravity=G) as world:
        world.reset(rest)
        for _ in range(int(3 * rate)):
            world.set_body_pose(rest)
            world.step()
        start = world.body_poses()[0][1].copy()
        pose = rest.copy()
        for s in range(int(0.5 * rate)):
            pose[:, 4] = rest[:, 4] + 0.2 * min(1.0, s / (0.1 * rate))
            world.set_body_pose(pose)
            world.step()
        assert world.body_poses()[0][1][0] - start[0] > 0.1


def _pushed_bob(speed, **world):
    """A bob hanging at rest, struck and pushed along +X by a static (bone-following) box moving at
    ``speed`` m/s for 0.3 s, in a FileWorld with the keyword arguments ``world``. Returns the gap
    (metres) between the bob's surface and the box's face after each step, negative when the bob is
    sunk into the box, and the bob's X (metres) after each step."""
    half = 0.05
    bodies, joints, keypoints = _pendulum(np.array([0.0, -ARM, 0.0]))
    start = PIVOT + [-0.2, -ARM, 0.0]  # the box's centre: its face 0.15 m - RADIUS from the bob
    bodies.append(_body(2, "box", [half, half, half], start, "static", group=2, bone=2))
    keypoints = np.concatenate([keypoints, start[None]])
    rate = PARAMS.file_step_rate
    rest = rest_transforms(keypoints).astype(np.float64)
    gaps, xs = [], []
    with FileWorld(bodies, joints, keypoints, np.array([-1, 0, -1]), 1.0 / rate, PARAMS.file_solver_iterations,
                   0.08, apparel=np.array([False, True, False]), erp=PARAMS.file_erp, gravity=G, **world) as world:
        world.reset(rest)
        for s in range(1, int(0.3 * rate) + 1):
            pose = rest.copy()
            pose[2, 4] += speed * s / rate
            world.set_body_pose(pose)
            world.step()
            xs.append(world.body_poses()[0][1][0])
            gaps.append(xs[-1] - RADIUS - (start[0] + speed * s / rate + half))
    return np.array(gaps), np.array(xs)


@pytest.mark.parametrize("speed", [0.5, 1.0])
def test_a_moving_body_pushes_apparel_at_its_own_speed_when_contacts_see_it_move(speed):
    # a critically damped contact spring (stiffness m w^2, damping 2 m w) whose damping takes the
    # pushing body as standing still settles where the spring's force balances the damping's drag at
    # the body's speed v: sunk 2 v / w into the body (27 mm at 1 m/s and 75 rad/s). Moving with the
    # body's speed (the players' kinematic bodies), the contact only has to take the bob from rest to
    # v when struck: it sinks less than v / w, and is not dragged once it moves with the body.
    w = PARAMS.file_contact_frequency
    still = _pushed_bob(speed, body_velocity=False)[0]
    assert -still[-12:].mean() == pytest.approx(2 * speed / w, rel=0.05)
    for world in ({"body_velocity": True}, {"contact_cap": 1000.0}):
        moving = _pushed_bob(speed, **world)[0]
        assert moving.min() > -speed / w and moving[-12:].mean() > -0.1 * 2 * speed / w, world


def test_a_capped_contact_limits_how_hard_a_body_pushes_a_link():
    # the box strikes the bob at 1 m/s: through an uncapped contact the bob is thrown to the box's
    # speed within a few steps (over 10 g); capped at 5 m/s^2 the contact accelerates it at most that
    # much (within 15%: the pendulum's pull, (g + v^2 / L) x / L along X, is taken off as for a
    # small swing) and the box passes into it instead
    rate, cap = PARAMS.file_step_rate, 5.0
    gaps, xs = _pushed_bob(1.0, contact_cap=1000.0)
    assert (np.abs(np.diff(xs, 2)) * rate ** 2).max() > 100.0
    gaps, xs = _pushed_bob(1.0, contact_cap=cap)
    x, speed = xs[1:-1] - PIVOT[0], (xs[2:] - xs[:-2]) * rate / 2
    from_contact = np.diff(xs, 2) * rate ** 2 + (G + speed ** 2 / ARM) * x / ARM
    assert np.abs(from_contact).max() < 1.15 * cap and gaps.min() < -0.05


@pytest.mark.parametrize("switch", ["file_body_velocity", "file_duplicate_ranges", "file_body_damping", "file_contact_cap"])
def test_an_opt_in_switch_enters_the_record_only_when_on(switch):
    """Off, an opt-in switch is absent from the run's JSON (the fingerprint of a run made without the
    switch); on, it is there; both read back to the same parameters."""
    import dataclasses

    from mimicbench.datagen.apparel.params import ApparelParams, SimParams, params_from_json

    off = ApparelParams()
    value = 20.0 if switch == "file_contact_cap" else True
    on = ApparelParams(dataclasses.replace(SimParams(), **{switch: value}))
    assert switch not in off.to_json()["simulation"]
    assert on.to_json()["simulation"][switch] == value
    assert params_from_json(off.to_json()) == off and params_from_json(on.to_json()) == on
