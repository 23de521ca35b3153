"""f_d of the MMDMC reference: EdgeConv grouped by apparel component, and the K = 3 history."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mmdmc.apparel import HISTORY, ApparelDynamics, apparel_components, component_neighbours


def two_patches():
    """Two separate triangle fans (components) of 5 vertices each, 1 m apart; faces (6, 3)."""
    ring = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [-0.1, 0, 0], [0, -0.1, 0]], np.float32)
    v = np.concatenate([ring, ring + [1.0, 0, 0]]).astype(np.float32)
    fan = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4]], np.int32)
    return v, np.concatenate([fan, fan + 5])


def inputs(v, frames=1, seed=0):
    g = torch.Generator().manual_seed(seed)
    a = len(v)
    rest = torch.as_tensor(v)[None]
    history = rest[:, None].repeat(1, HISTORY, 1, 1) + 0.01 * torch.randn(1, HISTORY, a, 3, generator=g)
    body = rest[:, None].repeat(1, frames + 1, 1, 1) + 0.01 * torch.randn(1, frames + 1, a, 3, generator=g)
    joints = torch.randn(1, frames + HISTORY, 4, 3, generator=g) * 0.1
    return history, body, rest, joints


def untrained_but_moving(model: ApparelDynamics) -> ApparelDynamics:
    """The model with a random (non-zero) last decoder layer: an untrained f_d outputs exactly zero,
    which would hide what a step reads."""
    g = torch.Generator().manual_seed(1)
    with torch.no_grad():
        model.decode[-1].weight.copy_(torch.randn(model.decode[-1].weight.shape, generator=g) * 0.5)
    return model


def test_components_and_neighbours_stay_within_a_component():
    v, f = two_patches()
    labels = apparel_components(f, np.ones(10, bool))
    assert len(set(labels[:5])) == 1 and len(set(labels[5:])) == 1 and labels[0] != labels[5]
    nb = component_neighbours(v, labels, k=8)  # more neighbours than a component has: repeats its own
    assert nb.shape == (10, 8)
    assert np.all(labels[nb] == labels[:, None])
    assert np.all(nb[:, 0] == np.arange(10))  # each vertex first
    # only the masked vertices count, in mask order
    mask = np.zeros(10, bool)
    mask[[0, 1, 2, 7]] = True
    assert apparel_components(f, mask).tolist()[:3] == [0, 0, 0] and len(set(apparel_components(f, mask))) == 2


def test_a_change_in_one_component_leaves_the_other_unchanged():
    torch.manual_seed(0)
    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    model = untrained_but_moving(ApparelDynamics(hidden=16, code=8).eval())
    history, body, rest, joints = inputs(v)
    x, _ = model.step(history, body, rest, joints[:, :4], nb)
    moved = history.clone()
    moved[:, :, :5] += 0.05  # displace the first component's states
    x2, _ = model.step(moved, body, rest, joints[:, :4], nb)
    assert torch.equal(x[:, 5:], x2[:, 5:])
    assert not torch.allclose(x[:, :5], x2[:, :5])


def test_rollout_reads_exactly_three_states():
    torch.manual_seed(0)
    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    model = untrained_but_moving(ApparelDynamics(hidden=16, code=8).eval())
    history, body, rest, joints = inputs(v, frames=4)
    seen = []
    step = model.step

    def spy(h, b, r, j, n):
        seen.append((h.clone(), b.clone(), j.clone()))
        return step(h, b, r, j, n)

    model.step = spy
    states, disp = model.rollout(history, body, rest, joints, nb)
    assert states.shape == (1, 4, 10, 3) and disp.shape == (1, 4, 10, 3)
    sequence = torch.cat([history, states], 1)  # x_{-3}, x_{-2}, x_{-1}, x_0 .. x_3
    assert len(seen) == 4
    for t, (h, b, j) in enumerate(seen):
        assert h.shape[1] == HISTORY == 3
        torch.testing.assert_close(h, sequence[:, t:t + 3])  # x_{t-3}, x_{t-2}, x_{t-1}: no older state
        torch.testing.assert_close(b, body[:, t:t + 2])       # s_{t-1}, s_t
        torch.testing.assert_close(j, joints[:, t:t + 4])     # joints t-3 .. t
    # the oldest state does change the step's output (it is read, through the acceleration)
    older = history.clone()
    older[:, 0] += 0.05
    assert not torch.allclose(step(older, body[:, :2], rest, joints[:, :4], nb)[0], step(history, body[:, :2], rest, joints[:, :4], nb)[0])
    with pytest.raises(ValueError, match="expected 3 states"):
        step(torch.cat([history, history[:, :1]], 1), body[:, :2], rest, joints[:, :4], nb)


def test_zero_displacement_keeps_the_offset_from_the_body():
    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    model = ApparelDynamics(hidden=16, code=8)  # untrained: its decoder starts at zero
    history, body, rest, joints = inputs(v)
    x, d = model.step(history, body, rest, joints[:, :4], nb)
    assert torch.all(d == 0)
    torch.testing.assert_close(x, body[:, 1] + history[:, -1] - body[:, 0])


def test_untrained_rollout_from_rest_is_the_body_pose():
    """From a start at rest on the body (history = the first body state, as at inference), an
    untrained f_d returns the body states frame by frame: x_t = s_t + (x_{t-1} - s_{t-1}) + 0."""
    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    model = ApparelDynamics(hidden=16, code=8)
    _, body, rest, joints = inputs(v, frames=5)
    body = torch.cat([body[:, :1], body[:, 1:]], 1)
    body[:, 0] = body[:, 1]  # frame -1 is frame 0, as at inference
    history = body[:, :1].repeat(1, HISTORY, 1, 1)
    states, _ = model.rollout(history, body, rest, joints, nb)
    torch.testing.assert_close(states, body[:, 1:])


def naive_rest_rollout(model, sb, rest, joints, nb):
    """A request's rollout written out step by step: at frame 0 the apparel rests on the body (the
    K = 3 states are s_0, s_{-1} = s_0) and the joints before frame 0 are frame 0's; then each frame
    reads the last three states, s_{t-1}, s_t and the joints t-3..t. sb (1, F, A, 3), joints (1, F, J, 3)."""
    states = [sb[:, 0]] * HISTORY
    out = []
    for t in range(sb.shape[1]):
        prev = sb[:, max(t - 1, 0)]
        jt = torch.stack([joints[:, max(t - d, 0)] for d in (3, 2, 1, 0)], 1)
        x, _ = model.step(torch.stack(states[-3:], 1), torch.stack([prev, sb[:, t]], 1), rest, jt, nb)
        states.append(x)
        out.append(x)
    return torch.stack(out, 1)


def test_training_rollout_from_rest_is_the_inference_rollout():
    """The apparel stage's from-rest rollout (apparel_start="clip") and inference's rollout of a request
    are one code path: on the same inputs both equal a naive step-by-step rollout from rest."""
    from types import SimpleNamespace

    from mimicbench.baselines.mmdmc.pipeline import rollout_from_body
    from mimicbench.baselines.mmdmc.training import apparel_states

    torch.manual_seed(0)
    v, f = two_patches()
    nb = component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4)
    model = untrained_but_moving(ApparelDynamics(hidden=16, code=8).eval())
    _, body, rest, joints = inputs(v, frames=7)
    sb, jt = body[:, 1:], joints[:, HISTORY:]  # 7 frames of body states and joints
    # inference: the whole mesh's body states (apparel vertices 0..9 among 3 body-only ones)
    mesh = torch.cat([sb[0], torch.zeros(7, 3, 3)], 1)
    prep = SimpleNamespace(rest_norm=np.concatenate([v, np.zeros((3, 3), np.float32)]))
    inferred = rollout_from_body(model, prep, mesh, jt[0], np.arange(10), nb)
    trained, _ = apparel_states(model, {"body": sb, "rest": rest, "joints": jt, "neighbours": torch.as_tensor(nb)},
                                {"bptt": 0})
    naive = naive_rest_rollout(model, sb, rest, jt, torch.as_tensor(nb))
    torch.testing.assert_close(trained[0], inferred)
    torch.testing.assert_close(trained, naive)
    assert float((trained.detach() - sb).abs().max()) > 1e-3  # it moved off the body: the comparison is not vacuous


def test_truncated_backpropagation_keeps_the_values_and_cuts_the_gradient():
    from mimicbench.baselines.mmdmc.pipeline import rollout_from_rest

    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    model = untrained_but_moving(ApparelDynamics(hidden=16, code=8))
    _, body, rest, joints = inputs(v, frames=6)
    grads = {}
    for k in (0, 2):
        sb = body[:, 1:].clone().requires_grad_(True)
        states, _ = rollout_from_rest(model, sb, rest, joints[:, HISTORY:], nb, truncate=k)
        grads[k] = torch.autograd.grad(states[:, -1].sum(), sb)[0]  # the last frame (5) against every body state
        if k == 0:
            full = states.detach()
        else:
            torch.testing.assert_close(states.detach(), full)
    assert grads[0][:, 0].abs().sum() > 0  # without truncation frame 5 reaches back to frame 0
    # with truncate=2 the states are detached at step 4: frame 5 sees only body states 3..5 (step 4 reads s_3, s_4)
    assert torch.all(grads[2][:, :3] == 0) and grads[2][:, 3:].abs().sum() > 0
    with pytest.raises(ValueError, match="truncate"):
        rollout_from_rest(model, body[:, 1:], rest, joints[:, HISTORY:], nb, truncate=-1)


def test_from_rest_rollouts_cover_every_scored_window_of_the_apparel_protocol():
    """rollout_span / scored_frames against the protocol's own request starts (burn_in_start): every
    window a case can score is the scored tail of a training rollout that starts where its request does."""
    from mimicbench.baselines.mmdmc.config import CONFIGS
    from mimicbench.baselines.mmdmc.training import rollout_span, scored_frames
    from mimicbench.benchmark.protocols.apparel import BURN_IN, WINDOW, burn_in_start

    for cfg in CONFIGS.values():
        assert (cfg["burn_in"], cfg["scored_window"]) == (BURN_IN, WINDOW)
    assert rollout_span(45, 90, 16) == ([0], 45)
    assert rollout_span(108, 90, 16) == ([0, 1, 2], 106)
    np.testing.assert_array_equal(scored_frames(0, 45, 16), np.ones(45, bool))
    np.testing.assert_array_equal(scored_frames(2, 106, 16), np.r_[np.zeros(90, bool), np.ones(16, bool)])
    for frames in (16, 45, 105, 106, 107, 150):
        starts, length = rollout_span(frames, BURN_IN, WINDOW)
        for w0 in range(frames - WINDOW + 1):
            q = burn_in_start(w0)
            assert q in starts and w0 + WINDOW - q <= length
            assert scored_frames(q, length, WINDOW)[w0 - q:w0 - q + WINDOW].all()
        # and a scored frame of a rollout is a frame some case scores from that start
        for s in starts:
            on = np.flatnonzero(scored_frames(s, length, WINDOW)) + s
            assert all(any(burn_in_start(w0) == s and w0 <= t < w0 + WINDOW for w0 in range(frames - WINDOW + 1))
                       for t in on)


def lagging_windows(n: int = 3, frames: int = 30, a: float = 0.3):
    """``n`` toy windows whose apparel lags the body as a first-order low-pass started at rest on it:
    x_0 = s_0, x_t = x_{t-1} + a (s_t - x_{t-1}) (a step f_d can express: d_t = (1 - a)(x_{t-1} - s_t) - u).
    The body (two patches) sways along x and y at a different frequency each window."""
    v, f = two_patches()
    nb = torch.as_tensor(component_neighbours(v, apparel_components(f, np.ones(10, bool)), k=4))
    out = []
    t = np.arange(frames, dtype=np.float32)
    for w in range(n):
        shift = np.stack([0.2 * np.sin(t * (0.2 + 0.1 * w)), 0.1 * np.sin(t * (0.3 + 0.05 * w)), 0 * t], 1)
        sb = v[None] + shift[:, None].astype(np.float32)  # (F, 10, 3)
        x = [sb[0]]
        for i in range(1, frames):
            x.append(x[-1] + a * (sb[i] - x[-1]))
        joints = np.stack([shift + [0, 0.5 * j, 0] for j in range(4)], 1).astype(np.float32)  # (F, 4, 3)
        out.append({"body": torch.as_tensor(sb)[None], "truth": torch.as_tensor(np.stack(x))[None],
                    "joints": torch.as_tensor(joints)[None], "rest": torch.as_tensor(v)[None], "neighbours": nb})
    return out


def test_overfit_a_few_from_rest_windows_of_a_lag():
    """The overfit test: a fresh f_d trained on three from-rest windows of a lag its inputs can express
    (rolled out through the same path as a request, with the presets' truncated backpropagation)
    removes much of the zero displacement's error. (Full backpropagation through the 30 frames,
    bptt 0, left it within 1% of the zero displacement's after the same 150 steps.)"""
    from mimicbench.baselines.mmdmc.config import CONFIGS
    from mimicbench.baselines.mmdmc.losses import vertex_l1
    from mimicbench.baselines.mmdmc.training import apparel_states

    config = {"bptt": CONFIGS["small"]["bptt"]}
    assert config["bptt"] == CONFIGS["paper"]["bptt"] > 0

    torch.manual_seed(0)
    windows = lagging_windows()
    model = ApparelDynamics(hidden=16, code=8)
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)

    def error():
        with torch.no_grad():
            return float(np.mean([float(vertex_l1(apparel_states(model, w, config)[0], w["truth"])) for w in windows]))

    zero = float(np.mean([float(vertex_l1(w["body"], w["truth"])) for w in windows]))
    assert abs(error() - zero) < 1e-7 and zero > 0.02  # an untrained f_d is the body pose; the lag is large
    for step in range(150):
        w = windows[step % len(windows)]
        loss = vertex_l1(apparel_states(model, w, config)[0], w["truth"])
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert error() < 0.6 * zero, (zero, error())
