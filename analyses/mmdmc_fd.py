"""Why f_d (MMDMC's apparel module) does or does not learn: its target, its inputs, and an overfit run.

    python analyses/mmdmc_fd.py TRAIN_SIM HELDOUT_SIM [--steps 300] [--windows 48]

Both folders are ``mimicbench datagen apparel`` outputs. Three parts, printed as tables:

1. **The target** (ground-truth apparel mask, every frame of every clip; cm at 1.70 m height):
   r = simulated apparel - the same vertices skinned rigidly to the body bone their chain hangs
   from (the body module's target, what ``mmdmc_no_apparel`` shows). ``|r|`` is what f_d must
   remove; ``static`` is what is left after each vertex's own time mean (a per-clip sag f_d could
   learn from the rest position); ``noise`` is r minus its 5-frame centred moving average (what
   no smooth displacement can fit), with its share of the time-varying power.
2. **The inputs** (teacher-forced one-step, as f_d's step sees them): the displacement f_d must
   output is d_t = r_t - r_{t-1}. A linear isotropic model (one coefficient per input vector, plus
   a constant vector) fitted on the training clips, R^2 on the held-out clips (1 - SSE / sum|d|^2,
   so 0 is a zero displacement): with f_d's own inputs (u, apparel velocity and acceleration, the
   body's velocity at the vertex), and with the body's acceleration at the vertex added.
3. **The overfit test** (``tests/test_mmdmc_training.py``'s few-steps test on more windows): the
   apparel stage's own batches (shipped f_c and f_s frozen, the shipped config) on ``--windows``
   fixed training windows and half as many held-out ones, a fresh f_d trained with AdamW on the
   training windows; vertex L1 (unit-height frame) on both sets, for windows started from the
   ground-truth history and from rest (as at inference), at steps 0, ..., ``--steps``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path[0] = str(REPO)  # run as a script: import from the repository root
CM = 170.0  # cm of a 1.70 m character


def _pairs(dataset: Path):
    """(Prepared, ClipPair, apparel rows, ground truth (F, A, 3), body target (F, A, 3)) per clip, metres."""
    from mimicbench.baselines.mmdmc.data import TrainingData, body_target_weights, posed
    from mimicbench.geometry.skinning import linear_blend_skinning
    from mimicbench.schemas.weights import SparseWeights

    data = TrainingData.load(dataset)
    for clip in data.clips:
        c = data.characters[clip.character_id]
        rows = np.flatnonzero(c.apparel)
        dense = body_target_weights(c)[rows]  # (A, Kb)
        full = np.zeros((len(rows), len(c.parents)), np.float32)
        full[:, c.body] = dense
        body = linear_blend_skinning(c.rest[rows], c.keypoints, SparseWeights.from_dense(full), clip.kinematic)
        yield c, clip, rows, posed(c, clip.simulated, rows).astype(np.float64), np.asarray(body, np.float64)


def target_table(dataset: Path) -> dict:
    """Part 1: sums over every clip of the target's size, its static part and its noise (cm at 1.70 m)."""
    acc = {"clips": 0, "n": 0, "abs": 0.0, "dyn": 0.0, "noise": 0.0, "p_dyn": 0.0, "p_noise": 0.0, "first": 0.0,
           "nf": 0}
    per_clip = []
    for c, clip, rows, x, s in _pairs(dataset):
        k = CM / c.height
        r = (x - s) * k  # (F, A, 3) cm at 1.70 m
        dyn = r - r.mean(0, keepdims=True)
        pad = np.concatenate([r[:1].repeat(2, 0), r, r[-1:].repeat(2, 0)])
        smooth = sum(pad[i:i + len(r)] for i in range(5)) / 5
        noise = r - smooth
        n = r.shape[0] * r.shape[1]
        acc["clips"] += 1
        acc["n"] += n
        acc["abs"] += np.linalg.norm(r, axis=-1).sum()
        acc["dyn"] += np.linalg.norm(dyn, axis=-1).sum()
        acc["noise"] += np.linalg.norm(noise, axis=-1).sum()
        acc["p_dyn"] += (dyn ** 2).sum()
        acc["p_noise"] += (noise ** 2).sum()
        per_clip.append((clip.name, np.linalg.norm(r, axis=-1).mean(), np.linalg.norm(dyn, axis=-1).mean(),
                         np.linalg.norm(noise, axis=-1).mean()))
    out = {"clips": acc["clips"], "abs_cm": acc["abs"] / acc["n"], "static_removed_cm": acc["dyn"] / acc["n"],
           "noise_cm": acc["noise"] / acc["n"], "noise_power_share": acc["p_noise"] / max(acc["p_dyn"], 1e-30)}
    by = {}
    for name, a, d, z in per_clip:
        by.setdefault(name.split("_")[0] if name.startswith("random") else name, []).append((a, d, z))
    out["by_clip"] = {k: tuple(np.mean(v, 0)) for k, v in sorted(by.items())}
    return out


def _features(x: np.ndarray, s: np.ndarray, scale: float):
    """Teacher-forced step inputs and target, per vertex and frame t >= 3, in cm at 1.70 m per frame.

    Returns (features (P, 6, 3): u, apparel velocity, apparel acceleration, body velocity, body
    acceleration, ones; target d (P, 3)).
    """
    r = (x - s) * scale
    xs, ss = x * scale, s * scale
    t = np.arange(3, len(x))
    u = r[t - 1]
    vx = xs[t - 1] - xs[t - 2]
    ax = xs[t - 1] - 2 * xs[t - 2] + xs[t - 3]
    vs = ss[t] - ss[t - 1]
    as_ = ss[t] - 2 * ss[t - 1] + ss[t - 2]
    ones = np.ones_like(u)
    f = np.stack([u, vx, ax, vs, as_, ones], -2).reshape(-1, 6, 3)
    return f, (r[t] - r[t - 1]).reshape(-1, 3)


def input_table(train: Path, held: Path, max_points: int = 400_000, seed: int = 0) -> dict:
    """Part 2: R^2 on held-out clips of linear isotropic models of d_t from the step's inputs."""
    rng = np.random.default_rng(seed)

    def gather(ds):
        fs, ys = [], []
        for c, clip, rows, x, s in _pairs(ds):
            f, y = _features(x, s, CM / c.height)
            fs.append(f)
            ys.append(y)
        f, y = np.concatenate(fs), np.concatenate(ys)
        if len(y) > max_points:
            keep = rng.choice(len(y), max_points, replace=False)
            f, y = f[keep], y[keep]
        return f, y

    ftr, ytr = gather(train)
    fte, yte = gather(held)
    out = {"points_train": len(ytr), "points_held": len(yte), "mean_abs_d_cm": float(np.linalg.norm(yte, axis=1).mean())}
    sets = {"f_d inputs (u, v_x, a_x, v_s)": [0, 1, 2, 3, 5], "f_d inputs + body acceleration a_s": [0, 1, 2, 3, 4, 5],
            "body acceleration a_s alone": [4, 5], "u alone (a spring)": [0, 5]}
    for name, cols in sets.items():
        # isotropic: one coefficient per input vector; the constant vector gets one per axis
        def design(f):
            vec = [f[:, i, :] for i in cols if i != 5]
            a = np.stack([v.reshape(-1) for v in vec], 1) if vec else np.zeros((f.shape[0] * 3, 0))
            axis = np.kron(np.ones((f.shape[0], 1)), np.eye(3))
            return np.concatenate([a, axis], 1)
        a_tr, a_te = design(ftr), design(fte)
        coef = np.linalg.solve(a_tr.T @ a_tr + 1e-6 * np.eye(a_tr.shape[1]), a_tr.T @ ytr.reshape(-1))
        pred = a_te @ coef
        sse = ((pred - yte.reshape(-1)) ** 2).sum()
        out[name] = {"r2_held": float(1 - sse / (yte ** 2).sum()), "cols": cols, "full_coef": coef,
                     "r2_train": float(1 - ((a_tr @ coef - ytr.reshape(-1)) ** 2).sum() / (ytr ** 2).sum()),
                     "coef": np.round(coef[: len(cols) - 1], 4).tolist()}
    return out


def _linear_rollout(ss: np.ndarray, hist: list, prev_s: list, coef: np.ndarray, cols: list[int], frames) -> list:
    """States of the linear step (``cols``/``coef`` of :func:`input_table`) at ``frames``, from the three
    history states ``hist`` and the two body states before the first frame ``prev_s`` (cm)."""
    states, prev_s, out = list(hist), list(prev_s), []
    for t in frames:
        x1, x2, x3 = states[-1], states[-2], states[-3]
        vec = {0: x1 - prev_s[-1], 1: x1 - x2, 2: x1 - 2 * x2 + x3, 3: ss[t] - prev_s[-1],
               4: ss[t] - 2 * prev_s[-1] + prev_s[-2]}
        d = sum(coef[j] * vec[i] for j, i in enumerate(i for i in cols if i != 5)) + coef[-3:]
        states.append(ss[t] + (x1 - prev_s[-1]) + d)
        prev_s.append(ss[t])
        out.append(states[-1])
    return out


def rollout_table(held: Path, coef: np.ndarray, cols: list[int], window: int = 16, every: int = 8) -> dict:
    """Part 2b: the fitted linear step rolled out over ``window``-frame windows of the held-out clips, from
    the ground-truth history (``gt``), from rest on the body at the window's first frame (``rest``, as
    ``bench run`` started a case before cases version 2) and from rest at the clip's first frame
    (``burn``: where the simulation started, as cases version 2 start a request; only the window's
    frames count), against a zero displacement; mean |x - truth| over apparel vertices and frames, cm
    at 1.70 m."""
    sums = {k: [0.0, 0] for k in ("gt_zero", "gt_linear", "rest_zero", "rest_linear", "burn_zero", "burn_linear")}

    def add(name, e):
        sums[name][0] += float(e.sum())
        sums[name][1] += e.size

    for c, clip, rows, x, s in _pairs(held):
        k = CM / c.height
        xs, ss = x * k, s * k
        whole = _linear_rollout(ss, [ss[0]] * 3, [ss[0], ss[0]], coef, cols, range(len(x)))  # from the clip start
        for t0 in range(3, len(x) - window + 1, every):
            for start in ("gt", "rest"):
                hist = [xs[t0 - 3 + i] for i in range(3)] if start == "gt" else [ss[t0]] * 3
                body_prev = ss[t0 - 1] if start == "gt" else ss[t0]
                zero_u = hist[-1] - body_prev
                prev_s = [ss[t0 - 2] if start == "gt" else ss[t0], body_prev]
                frames = range(t0, t0 + window)
                for t, state in zip(frames, _linear_rollout(ss, hist, prev_s, coef, cols, frames)):
                    add(f"{start}_linear", np.linalg.norm(state - xs[t], axis=-1))
                    add(f"{start}_zero", np.linalg.norm(ss[t] + zero_u - xs[t], axis=-1))
            for t in range(t0, t0 + window):
                add("burn_linear", np.linalg.norm(whole[t] - xs[t], axis=-1))
                add("burn_zero", np.linalg.norm(ss[t] - xs[t], axis=-1))
    return {k: v[0] / max(v[1], 1) for k, v in sums.items()}


def _context(dataset: Path, config: dict):
    from mimicbench.training.checkpoint import load_module
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    model = trainable("mmdmc")
    ck = REPO / "baselines" / "mmdmc" / "checkpoints"
    frozen = {}
    for need in ("seg", "body"):
        m = load_module(ck / f"{need}.safetensors", lambda c, n=need: model.stage(n).build(c, None))
        for p in m.parameters():
            p.requires_grad_(False)
        frozen[need] = m
    return StageContext(dataset, torch.device("cpu"), config, frozen)


def _windows(dataset: Path, config: dict, n: int, rest_start: float, seed: int) -> list[dict]:
    from mimicbench.training.registry import trainable

    cfg = {**config, "apparel_start": "window", "rest_start": rest_start, "batch_size": 1,  # version 6's windows
           "apparel": {**config.get("apparel", {}), "batches_per_epoch": n}}
    ctx = _context(dataset, cfg)
    st = trainable("mmdmc").stage("apparel")
    out = []
    for b in st.batches(cfg, ctx, np.random.default_rng(seed)):
        out.append({k: torch.as_tensor(v) if isinstance(v, np.ndarray) else v for k, v in b.items()})
    return out


def overfit_table(train: Path, held: Path, steps: int, windows: int, lr: float, seed: int = 0) -> list[tuple]:
    """Part 3: vertex L1 on fixed training / held-out windows (GT-history and rest starts) while a
    fresh f_d trains on the training windows (both starts)."""
    from mimicbench.training.registry import trainable
    from mimicbench.baselines.mmdmc.losses import vertex_l1

    model = trainable("mmdmc")
    config = model.config("small")
    config.update({"weights_on": "body", "seg_body_clips": "kinematic", "seg_inputs": "bones",
                   "apparel_skinning": "attachment", "mask_by_piece": True, "weight_smoothing_radius": 0.08,
                   "body_prior": "piece"})
    sets = {("train", "gt"): _windows(train, config, windows, 0.0, seed),
            ("train", "rest"): _windows(train, config, windows, 1.0, seed),
            ("held", "gt"): _windows(held, config, windows // 2, 0.0, seed + 1),
            ("held", "rest"): _windows(held, config, windows // 2, 1.0, seed + 1)}
    st = model.stage("apparel")
    torch.manual_seed(seed)
    module = st.build(config, None)
    opt = torch.optim.AdamW(module.parameters(), lr=lr, weight_decay=config["weight_decay"])
    ctx = _context(train, config)
    fit = sets["train", "gt"] + sets["train", "rest"]

    @torch.no_grad()
    def evaluate():
        row = {}
        for key, ws in sets.items():
            row[key] = float(np.mean([float(vertex_l1(module.rollout(b["history"], b["body"], b["rest"], b["joints"],
                                                                     b["neighbours"])[0], b["truth"])) for b in ws]))
        return row

    rows = [(0, evaluate())]
    order = np.random.default_rng(seed).permutation(len(fit) * (steps // len(fit) + 1)) % len(fit)
    every = max(1, steps // 6)
    t0 = time.perf_counter()
    for i in range(1, steps + 1):
        b = fit[order[i - 1]]
        loss = st.loss(module, b, ctx)
        opt.zero_grad()
        loss["total"].backward()
        opt.step()
        if i % every == 0 or i == steps:
            rows.append((i, evaluate()))
            print(f"  step {i}: {rows[-1][1]}  ({time.perf_counter() - t0:.0f} s)", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("train", type=Path)
    ap.add_argument("held", type=Path)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--windows", type=int, default=48)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--parts", default="1,2,3")
    args = ap.parse_args()
    torch.set_num_threads(1)
    parts = set(args.parts.split(","))
    if "1" in parts:
        for name, ds in (("train", args.train), ("held", args.held)):
            t = target_table(ds)
            print(f"[1] {name}: {t['clips']} clips; |r| {t['abs_cm']:.3f} cm; after each vertex's time mean "
                  f"{t['static_removed_cm']:.3f} cm; noise (r - 5-frame mean) {t['noise_cm']:.3f} cm, "
                  f"{100 * t['noise_power_share']:.1f}% of the time-varying power")
            for k, (a, d, z) in t["by_clip"].items():
                print(f"      {k:14s} |r| {a:.3f}  less static {d:.3f}  noise {z:.3f}")
    if "2" in parts:
        t = input_table(args.train, args.held)
        print(f"[2] one-step d_t: {t['points_train']} training points, {t['points_held']} held out; "
              f"mean |d| {t['mean_abs_d_cm']:.4f} cm a frame")
        for k, v in t.items():
            if isinstance(v, dict):
                print(f"      {k:36s} R2 held {v['r2_held']:.3f} (train {v['r2_train']:.3f}) coef {v['coef']}")
        fd = t["f_d inputs (u, v_x, a_x, v_s)"]
        r = rollout_table(args.held, fd["full_coef"], fd["cols"])
        print(f"[2b] that linear step rolled out over 16-frame held-out windows, mean error cm at 1.70 m: from the "
              f"ground-truth history {r['gt_linear']:.3f} (zero displacement {r['gt_zero']:.3f}); from rest on the "
              f"body {r['rest_linear']:.3f} (zero displacement {r['rest_zero']:.3f}); from rest at the clip's first "
              f"frame (burn-in) {r['burn_linear']:.3f} (zero displacement {r['burn_zero']:.3f})")
    if "3" in parts:
        rows = overfit_table(args.train, args.held, args.steps, args.windows, args.lr)
        print("[3] step | train gt | train rest | held gt | held rest (vertex L1, unit-height frame)")
        for i, r in rows:
            print(f"      {i:5d} | {r['train', 'gt']:.5f} | {r['train', 'rest']:.5f} | {r['held', 'gt']:.5f} | "
                  f"{r['held', 'rest']:.5f}")


if __name__ == "__main__":
    main()
