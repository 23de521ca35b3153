"""The body-history f_d (methods version 8): its inputs against a naive loop and hand values, its
invariance to the character's heading, its zero start, and that it learns a lag from the history."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from mimicbench.baselines.mmdmc.apparel_history import (FEATURES, LAGS, POSITION_SCALE, REST_SCALE, ROTATION_SCALE,
                                             BodyHistoryApparel, frame_bones, frame_rotations, history_features,
                                             rest_offsets)


def _random_motion(rng, f=40, a=5):
    body = rng.normal(size=(1, f, a, 3)).cumsum(1) * 0.01
    rot = Rotation.from_rotvec(rng.normal(size=(f * a, 3)) * 0.8).as_matrix().reshape(1, f, a, 3, 3)
    rest = rng.normal(size=(1, a, 3)) * 0.1
    return body, rot, rest


def _naive(body, rot, rest):
    """The features written out one frame, vertex and lag at a time with scipy's rotations."""
    _, f, a, _ = body.shape
    out = np.zeros((f, a, FEATURES))
    for t in range(f):
        for i in range(a):
            local = rot[0, t, i].T
            row = list(rest[0, i] * REST_SCALE) + list(local @ np.array([0.0, 1.0, 0.0]))
            pos, turn = [], []
            for lag in LAGS:
                then = max(t - lag, 0)
                pos += list(local @ (body[0, then, i] - body[0, t, i]) * POSITION_SCALE)
                rv = Rotation.from_matrix(local @ rot[0, then, i]).as_rotvec()
                angle = np.linalg.norm(rv)
                turn += list((rv / angle * np.sin(angle) if angle > 0 else np.zeros(3)) * ROTATION_SCALE)
            out[t, i] = row + pos + turn
    return out


def test_history_features_match_a_naive_loop():
    body, rot, rest = _random_motion(np.random.default_rng(0))
    got = history_features(torch.as_tensor(body), torch.as_tensor(rot), torch.as_tensor(rest))[0].numpy()
    np.testing.assert_allclose(got, _naive(body, rot, rest), atol=1e-9)


def test_history_features_by_hand_for_a_quarter_turn_about_up():
    # the frame bone turns 90 degrees about +Y at frame 5 and stays; the vertex stands still at (1, 0, 0)
    f = 12
    rot = np.tile(np.eye(3), (1, f, 1, 1, 1))
    rot[0, 5:, 0] = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    body = np.tile([1.0, 0.0, 0.0], (1, f, 1, 1))
    feats = history_features(torch.as_tensor(body), torch.as_tensor(rot), torch.zeros(1, 1, 3, dtype=torch.float64))[0]
    turns = feats[:, 0, 6 + 3 * len(LAGS):].reshape(f, len(LAGS), 3).numpy()
    np.testing.assert_allclose(feats[:, 0, 3:6].numpy(), np.tile([0, 1, 0], (f, 1)), atol=1e-12)  # up stays up
    for t in range(f):
        for j, lag in enumerate(LAGS):
            # seen from the turned bone, the bone lag frames ago is turned back by 90 degrees: sin 90 * (0, -1, 0)
            expect = [0, -ROTATION_SCALE, 0] if t >= 5 and max(t - lag, 0) < 5 else [0, 0, 0]
            np.testing.assert_allclose(turns[t, j], expect, atol=1e-12)
    assert np.abs(feats[:, 0, 6:6 + 3 * len(LAGS)].numpy()).max() == 0  # the vertex never moved


def test_history_features_do_not_depend_on_the_heading():
    body, rot, rest = _random_motion(np.random.default_rng(1))
    yaw = Rotation.from_euler("y", 73, degrees=True).as_matrix()
    turned = (yaw @ body[..., None])[..., 0] + np.array([3.0, 0.0, -2.0])
    a = history_features(torch.as_tensor(body), torch.as_tensor(rot), torch.as_tensor(rest))
    b = history_features(torch.as_tensor(turned), torch.as_tensor(yaw @ rot), torch.as_tensor(rest))
    np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-9)


def test_untrained_model_is_the_body_and_an_offset_is_turned_with_the_frame_bone():
    body, rot, rest = _random_motion(np.random.default_rng(2))
    args = [torch.as_tensor(x, dtype=torch.float32) for x in (body, rot, rest)]
    model = BodyHistoryApparel(hidden=16, layers=2)
    states, offsets = model.states(*args)
    assert torch.equal(states, args[0]) and offsets.abs().max() == 0
    with torch.no_grad():
        model.net[-1].bias.copy_(torch.tensor([0.0, 0.0, 2.0]))  # 2 * OUTPUT_SCALE along the bone's z
    states, _ = model.states(*args, frames=torch.tensor([3, 7]))
    expect = body[0, [3, 7]] + rot[0, [3, 7], :, :, 2] * 0.1
    np.testing.assert_allclose(states[0].detach().numpy(), expect, atol=1e-6)


def test_frames_blend_the_largest_weights_bones_by_hand():
    w = np.array([[0.1, 0.6, 0.0, 0.3, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    bones, fw = frame_bones(w, count=2)
    assert bones.tolist() == [[1, 3], [2, 0]]
    np.testing.assert_allclose(fw, [[2 / 3, 1 / 3], [1, 0]], rtol=1e-6)
    np.testing.assert_allclose(fw.sum(1), 1.0, rtol=1e-6)
    # bone 0 still, bone 1 turned 90 degrees about Y; a 50/50 vertex's frame is 45 degrees about Y (the
    # normalised sum of two quaternions is their slerp midpoint), also when bone 1's quaternion is
    # given as its negative (the same rotation)
    q90 = np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])
    for sign in (1.0, -1.0):
        transforms = np.zeros((1, 2, 7))
        transforms[0, 0, :4] = [1.0, 0.0, 0.0, 0.0]
        transforms[0, 1, :4] = sign * q90
        got = frame_rotations(torch.as_tensor(transforms), torch.tensor([[0, 1], [1, 0]]),
                              torch.tensor([[0.5, 0.5], [1.0, 0.0]], dtype=torch.float64))[0].numpy()
        np.testing.assert_allclose(got[0], Rotation.from_euler("y", 45, degrees=True).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(got[1], Rotation.from_euler("y", 90, degrees=True).as_matrix(), atol=1e-12)
    heads = np.array([[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    np.testing.assert_allclose(rest_offsets(np.array([[1.0, 1.0, 0.0]]), heads, np.array([[1, 0]]),
                                            np.array([[0.25, 0.75]])), [[1.0, 0.5, 0.0]])


def test_it_learns_a_lag_that_only_the_history_shows():
    """Toy: each apparel vertex trails its body state by 3 frames (x_t = s_{t-3}); f_d must learn
    r_t = s_{t-3} - s_t, which its lag-3 position input holds. A zero offset leaves |r|."""
    rng = np.random.default_rng(4)
    torch.manual_seed(0)
    clips = []
    for _ in range(6):
        body, rot, rest = _random_motion(rng, f=30, a=6)
        truth = body[:, np.maximum(np.arange(30) - 3, 0)]
        clips.append([torch.as_tensor(x, dtype=torch.float32) for x in (body, rot, rest, truth)])
    train, held = clips[:4], clips[4:]
    model = BodyHistoryApparel(hidden=64, layers=2)
    opt = torch.optim.Adam(model.parameters(), 3e-3)
    for step in range(400):
        body, rot, rest, truth = train[step % len(train)]
        loss = (model.states(body, rot, rest)[0] - truth).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        err = np.mean([float((model.states(b, r, o)[0] - t).norm(dim=-1).mean()) for b, r, o, t in held])
    zero = np.mean([float((b - t).norm(dim=-1).mean()) for b, _, _, t in held])
    assert err < 0.35 * zero, (err, zero)


def test_offset_smoothing_averages_over_component_neighbours_by_hand():
    from mimicbench.baselines.mmdmc.apparel_history import smooth_offsets

    # a strip of 4 vertices, each with itself and its next along the strip; the last with itself twice
    nb = torch.tensor([[0, 1], [1, 2], [2, 3], [3, 3]])
    off = torch.tensor([[0.0, 0, 0], [2.0, 0, 0], [4.0, 0, 0], [8.0, 0, 0]])
    np.testing.assert_allclose(smooth_offsets(off, nb, 1)[:, 0].numpy(), [1, 3, 6, 8])
    np.testing.assert_allclose(smooth_offsets(off, nb, 2)[:, 0].numpy(), [2, 4.5, 7, 8])
    assert torch.equal(smooth_offsets(off, None, 0), off)
    # a constant offset (a whole garment swung the same way) is left as it is
    np.testing.assert_allclose(smooth_offsets(torch.ones(2, 4, 3), nb, 3).numpy(), np.ones((2, 4, 3)))
    with pytest.raises(ValueError, match="neighbours"):
        smooth_offsets(off, None, 1)


def test_the_modules_smoothing_passes_average_its_offsets():
    from mimicbench.baselines.mmdmc.apparel_history import smooth_offsets

    body, rot, rest = [torch.as_tensor(x, dtype=torch.float32) for x in _random_motion(np.random.default_rng(5), a=4)]
    nb = torch.tensor([[0, 1], [1, 2], [2, 3], [3, 3]])
    torch.manual_seed(0)
    plain = BodyHistoryApparel(hidden=8, layers=1)
    torch.nn.init.normal_(plain.net[-1].weight)
    smoothed = BodyHistoryApparel(hidden=8, layers=1, smoothing=2)
    smoothed.load_state_dict(plain.state_dict())
    with torch.no_grad():
        _, raw = plain.states(body, rot, rest)
        states, off = smoothed.states(body, rot, rest, neighbours=nb)
    np.testing.assert_allclose(off.numpy(), smooth_offsets(raw, nb, 2).numpy(), atol=1e-7)
    np.testing.assert_allclose(states.numpy(), (body + off).numpy(), atol=1e-7)
    with pytest.raises(ValueError, match="passes"):
        BodyHistoryApparel(smoothing=-1)


def test_the_configs_arap_weight_reaches_the_module_and_a_negative_one_is_refused():
    from mimicbench.baselines.mmdmc.apparel_arap import ITERATIONS
    from mimicbench.baselines.mmdmc.training import build_apparel

    plain = build_apparel({"apparel_model": "body_history", "history_hidden": 8, "history_layers": 1})
    assert plain.arap == 0.0 and plain.arap_iterations == ITERATIONS
    kept = build_apparel({"apparel_model": "body_history", "history_hidden": 8, "history_layers": 1,
                          "history_arap": 0.03, "history_arap_iterations": 3})
    assert kept.arap == 0.03 and kept.arap_iterations == 3
    with pytest.raises(ValueError, match="arap"):
        BodyHistoryApparel(arap=-0.1)


def test_with_still_zero_a_still_body_keeps_its_skinned_apparel_and_motion_still_moves_it():
    rng = np.random.default_rng(9)
    body, rot, rest = [torch.as_tensor(x, dtype=torch.float32) for x in _random_motion(rng, f=12, a=5)]
    torch.manual_seed(1)
    free = BodyHistoryApparel(hidden=8, layers=1)
    torch.nn.init.normal_(free.net[-1].weight)
    torch.nn.init.normal_(free.net[-1].bias)
    still = BodyHistoryApparel(hidden=8, layers=1, still_zero=True)
    still.load_state_dict(free.state_dict())
    # a body that stands still in a turned pose: every frame is frame 0
    standing, turned = body[:, :1].expand_as(body).clone(), rot[:, :1].expand_as(rot).clone()
    with torch.no_grad():
        _, free_off = free.states(standing, turned, rest)
        states, off = still.states(standing, turned, rest)
        np.testing.assert_allclose(states.numpy(), standing.numpy(), atol=1e-7)
        assert free_off.abs().max() > 1e-3  # the plain MLP's answer is not zero there
        # moving: the MLP's offset less the one the same frame would have with the lag inputs zero
        _, moved = still.states(body, rot, rest)
        feats = history_features(body, rot, rest)
        calm = feats.clone()
        calm[..., 6:] = 0.0
        expected = (rot @ (free(feats) - free(calm))[..., None])[..., 0]
    np.testing.assert_allclose(moved.numpy(), expected.numpy(), atol=1e-6)
    assert moved.abs().max() > 1e-3
