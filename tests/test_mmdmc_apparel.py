"""f_d of the MMDMC reference: EdgeConv grouped by apparel component, and the K = 3 history."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from baselines.mmdmc.apparel import HISTORY, ApparelDynamics, apparel_components, component_neighbours


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
