"""How much of the apparel's lag a step model could remove from rest, at best: a damped oscillator.

    python analyses/mmdmc_fd_ceiling.py TRAIN_SIM HELDOUT_SIM [--clips 60]

Both folders are ``mimicbench datagen apparel`` outputs. The target is f_d's (``analyses/mmdmc_fd.py``):
r = simulated apparel - the same vertices carried rigidly by the body bone their chain hangs from
(ground-truth mask; cm at 1.70 m). A request of the apparel protocol starts at rest on the body at
the clip's first frame, so the model here does too: per vertex, the offset r is a damped spring
driven by the body's acceleration there (frames as the time unit),

    w_t = (1 - c) w_{t-1} - k r_{t-1} - g a_t,   r_t = r_{t-1} + w_t,   r_{-1} = w_{-1} = 0,

with a_t = s_t - 2 s_{t-1} + s_{t-2} the rigidly carried position's second difference (the body at
rest before frame 0). g = 0 is a zero displacement (``mmdmc_no_apparel``); g = 1, k = c = 0 a free
particle that keeps its place while the body moves away. Stable for 0 < c <= 1 and small k.

Printed (mean |r_pred - r| over every apparel vertex and frame, against a zero displacement's |r|):
1. (k, c, g) fitted on a grid on the training clips, scored on the held-out ones, overall and by clip;
2. an oracle: for a few (k, c), one gain g per vertex fitted on the held-out clip itself (least
   squares, r is linear in g), an upper bound for any model of this family that also knew each vertex's
   response. If that bound is small, no step model rolled out from rest can remove much of r.
"""
from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(REPO)  # run as a script: import from the repository root

K_GRID = (0.01, 0.03, 0.1, 0.3)
C_GRID = (0.05, 0.15, 0.4, 0.8)
G_GRID = (0.0, 0.25, 0.5, 0.75, 1.0)


def oscillator_rollout(carried: np.ndarray, k: float, c: float, g: float) -> np.ndarray:
    """(F, A, 3) offsets r from rest at frame 0 for rigidly carried positions ``carried`` (F, A, 3), any
    length unit (the offsets come in it); k, c, g per frame as in the module docstring."""
    s = np.asarray(carried, np.float64)
    padded = np.concatenate([s[:1], s[:1], s])
    accel = padded[2:] - 2 * padded[1:-1] + padded[:-2]  # (F, A, 3)
    r, w, out = np.zeros_like(s[0]), np.zeros_like(s[0]), np.empty_like(s)
    for t in range(len(s)):
        w = (1.0 - c) * w - k * r - g * accel[t]
        r = r + w
        out[t] = r
    return out


def per_vertex_gain(response: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(A,) least-squares gains g_v with target (F, A, 3) ~ g_v * response (F, A, 3) (the g = 1 rollout)."""
    return (response * target).sum(axis=(0, 2)) / np.maximum((response * response).sum(axis=(0, 2)), 1e-12)


def clips_of(dataset: Path, limit: int) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """Up to ``limit`` clips as (r (F, A, 3), carried (F, A, 3), clip name), cm at 1.70 m."""
    from analyses.mmdmc_fd import CM, _pairs

    out = []
    for c, clip, rows, x, s in _pairs(dataset):
        if len(out) >= limit:
            break
        scale = CM / c.height
        out.append(((x - s) * scale, s * scale, clip.name))
    return out


def error(clips, predict) -> tuple[float, float]:
    """Mean |predict(r, carried) - r| and mean |r| over every vertex and frame of ``clips``."""
    e = z = n = 0.0
    for r, s, _ in clips:
        e += np.linalg.norm(predict(r, s) - r, axis=-1).sum()
        z += np.linalg.norm(r, axis=-1).sum()
        n += r.shape[0] * r.shape[1]
    return e / n, z / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("train", type=Path)
    ap.add_argument("held", type=Path)
    ap.add_argument("--clips", type=int, default=60, help="clips read from each folder (default 60)")
    args = ap.parse_args()
    train, held = clips_of(args.train, args.clips), clips_of(args.held, args.clips)
    fits = {(k, c, g): error(train, lambda r, s, p=(k, c, g): oscillator_rollout(s, *p))[0]
            for k, c, g in itertools.product(K_GRID, C_GRID, G_GRID)}
    k, c, g = min(fits, key=fits.get)
    e, z = error(held, lambda r, s: oscillator_rollout(s, k, c, g))
    print(f"[1] fitted on {len(train)} training clips: k={k:g} c={c:g} g={g:g}; held out ({len(held)} clips): "
          f"{e:.3f} cm against a zero displacement's {z:.3f} ({100 * (1 - e / z):.1f}% removed)")
    for kind in sorted({name for *_, name in held}):
        e, z = error([x for x in held if x[2] == kind], lambda r, s: oscillator_rollout(s, k, c, g))
        print(f"      {kind:10s} {e:.3f} against {z:.3f}")
    for kk, cc in sorted({(k, c), (0.1, 0.4), (0.03, 0.15), (0.01, 0.05)}, reverse=True):
        def oracle(r, s, kk=kk, cc=cc):
            response = oscillator_rollout(s, kk, cc, 1.0)
            return response * per_vertex_gain(response, r)[None, :, None]
        e, z = error(held, oracle)
        print(f"[2] oracle gain per vertex, k={kk:g} c={cc:g}: {e:.3f} cm against {z:.3f} ({100 * (1 - e / z):.1f}% removed)")


if __name__ == "__main__":
    main()
