"""analyses/mmdmc_fd_ceiling.py: the damped-oscillator rollout and the per-vertex gain, against values
worked out by hand and a naive loop."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location(
    "mmdmc_fd_ceiling", Path(__file__).resolve().parents[1] / "analyses" / "mmdmc_fd_ceiling.py")
ceiling = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ceiling)


def _walk(frames: int = 12, points: int = 3) -> np.ndarray:
    """(F, A, 3) positions carried by a body that stands at frame 0, then moves 0.5 along x a frame."""
    s = np.zeros((frames, points, 3))
    s[:, :, 0] = 0.5 * np.maximum(np.arange(frames), 0)[:, None]
    s[:, :, 1] = np.arange(points)[None]
    return s


def test_a_free_particle_keeps_its_place_while_the_body_walks_away():
    # g = 1, k = c = 0: nothing holds the apparel, so it stays where it was at rest: r_t = -(s_t - s_0)
    s = _walk()
    r = ceiling.oscillator_rollout(s, 0.0, 0.0, 1.0)
    np.testing.assert_allclose(r, -(s - s[:1]), atol=1e-12)


def test_zero_gain_is_a_zero_displacement_and_the_rollout_matches_a_naive_loop():
    s = np.random.default_rng(0).normal(size=(9, 4, 3)).cumsum(axis=0)
    assert not ceiling.oscillator_rollout(s, 0.3, 0.4, 0.0).any()
    k, c, g = 0.3, 0.4, 0.7
    r, w, prev = np.zeros((4, 3)), np.zeros((4, 3)), [s[0], s[0]]  # body at rest before frame 0
    for t in range(len(s)):
        a = s[t] - 2 * prev[-1] + prev[-2]
        w = (1 - c) * w - k * r - g * a
        r = r + w
        np.testing.assert_allclose(ceiling.oscillator_rollout(s, k, c, g)[t], r, atol=1e-12)
        prev.append(s[t])


def test_the_spring_brings_a_stopped_walk_back_to_the_body():
    # the body walks 5 frames and stops: a damped spring (k 0.2, c 0.5) pulls the lagging apparel back
    s = _walk(60)
    s[6:, :, 0] = s[5, :, 0]
    r = ceiling.oscillator_rollout(s, 0.2, 0.5, 1.0)
    assert np.abs(r[5]).max() > 0.1
    assert np.abs(r[-1]).max() < 1e-3


def test_the_per_vertex_gain_is_the_least_squares_one():
    response = np.random.default_rng(1).normal(size=(7, 5, 3))
    gains = np.array([0.0, 0.5, -1.0, 2.0, 0.25])
    np.testing.assert_allclose(ceiling.per_vertex_gain(response, response * gains[None, :, None]), gains, atol=1e-12)
    # with noise orthogonal to the response, the gain is unchanged
    noise = np.random.default_rng(2).normal(size=response.shape)
    noise -= response * ceiling.per_vertex_gain(response, noise)[None, :, None]
    np.testing.assert_allclose(ceiling.per_vertex_gain(response, response * gains[None, :, None] + noise), gains, atol=1e-9)
