"""Training the MMDMC reference with the shared trainer, at toy size: each stage's loss drops over a
few steps, and a checkpoint round-trips and resumes."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.training.checkpoint import load_module
from mimicbench.training.loop import train_stage
from mimicbench.training.registry import trainable
from mimicbench.training.stage import StageContext

STAGES = ("seg", "body", "apparel")
pytestmark = pytest.mark.slow  # simulates a zoo character with pybullet, then trains every stage


def tiny_config() -> dict:
    cfg = trainable("mmdmc").config("small")
    cfg.update({"points": 192, "batch_size": 2, "batches_per_epoch": 2, "window": 3, "apparel_points": 200,
                "seg_hidden": 8, "body_hidden": 8, "apparel_hidden": 8, "code": 4,
                # an untrained f_c finds no apparel; in this toy every vertex counts as apparel
                "threshold": 0.0})
    for s in STAGES:
        cfg[s] = {"epochs": 1}
    return cfg


@pytest.fixture(scope="module")
def apparel_data(tmp_path_factory):
    """One zoo apparel character with one clip, simulated by the apparel stage."""
    from mimicbench.datagen.apparel.stage import simulate_dataset
    from mimicbench.datagen.zoo.dataset import build_zoo

    root = tmp_path_factory.mktemp("mmdmc")
    build_zoo(root / "zoo", 1, seed=5, categories=["apparel"], clips_per_character=1, progress=False)
    simulate_dataset(root / "zoo", root / "sim", progress=False)
    return root / "sim"


@pytest.fixture(scope="module")
def run(apparel_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("mmdmc_run")
    for s in STAGES:
        train_stage("mmdmc", s, apparel_data, out, tiny_config(), epochs=1, seed=0, progress=False)
    return out


def context(dataset, run, stage, cfg):
    model = trainable("mmdmc")
    frozen = {}
    for need in model.stage(stage).needs:
        m = load_module(run / need / "model.safetensors", lambda c, n=need: model.stage(n).build(c, None))
        for p in m.parameters():
            p.requires_grad_(False)
        frozen[need] = m
    return StageContext(dataset, torch.device("cpu"), cfg, frozen)


def after_steps(st, module, batch, ctx, term: str = "total", lr: float = 3e-3, steps: int = 12) -> dict:
    """The stage's loss terms (floats) after ``steps`` AdamW steps on ``term`` of one batch."""
    opt = torch.optim.AdamW(module.parameters(), lr=lr)
    for _ in range(steps):
        loss = st.loss(module, batch, ctx)
        opt.zero_grad()
        loss[term].backward()
        opt.step()
    return {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}


def after_descent(st, module, batch, ctx, term: str = "total", size: float = 1e-4,
                  part: str = "") -> tuple[float, float, float, float]:
    """``term`` before and after one step of norm ``size`` against its gradient over all parameters, with the
    gradient's norm over all parameters and over those whose names start with ``part``.

    A term descends along its gradient when ``after < before - 0.5 * size * norm`` (Armijo's condition): unlike a
    dozen optimiser steps, whose result on a steep or nearly flat term differs between CPUs, the first-order
    decrease holds on every machine, and it fails for a term that the parameters do not reach."""
    loss = st.loss(module, batch, ctx)[term]
    named = [(n, p) for n, p in module.named_parameters() if p.requires_grad]
    grads = torch.autograd.grad(loss, [p for _, p in named], allow_unused=True)
    sq = {n: float(g.pow(2).sum()) if g is not None else 0.0 for (n, _), g in zip(named, grads)}
    norm = sum(sq.values()) ** 0.5
    assert norm > 0, f"{term} does not depend on the module's parameters"
    with torch.no_grad():
        for (_, p), g in zip(named, grads):
            if g is not None:
                p -= size * g / norm
    after = float(st.loss(module, batch, ctx)[term].detach())
    return float(loss.detach()), after, norm, sum(v for n, v in sq.items() if n.startswith(part)) ** 0.5


def descends(st, module, batch, ctx, term: str = "total", size: float = 1e-4) -> bool:
    """Whether one step of norm ``size`` against ``term``'s gradient lowers it by Armijo's margin."""
    before, after, norm, _ = after_descent(st, module, batch, ctx, term, size)
    return after < before - 0.5 * size * norm


@pytest.mark.parametrize("stage", STAGES)
def test_each_stage_loss_descends_along_its_gradient(apparel_data, run, stage):
    cfg = tiny_config()
    ctx = context(apparel_data, run, stage, cfg)
    st = trainable("mmdmc").stage(stage)
    torch.manual_seed(0)
    module = st.build(cfg, ctx)
    batch = next(iter(st.batches(cfg, ctx, np.random.default_rng(0))))
    batch = {k: torch.as_tensor(v) if isinstance(v, np.ndarray) else v for k, v in batch.items()}
    first = {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}
    assert all(np.isfinite(v) for v in first.values()), first
    assert descends(st, module, batch, ctx), stage
    # the term that dominates each stage's total descends too (the body's total starts on the geodesic
    # prior's near-right weights, where the smoothness term leads, so it is judged by its total)
    main = {"seg": "bce", "apparel": "vertex"}.get(stage)
    if main:
        assert descends(st, module, batch, ctx, main), stage


def test_checkpoint_round_trips_and_resumes(apparel_data, run, tmp_path):
    cfg = tiny_config()
    st = trainable("mmdmc").stage("body")
    # round trip: the stored module gives the same weights as the file holds, and the same outputs
    m = load_module(run / "body" / "model.safetensors", lambda c: st.build(c, None))
    from safetensors.torch import load_file

    stored = load_file(str(run / "body" / "model.safetensors"))
    for k, v in m.state_dict().items():
        assert torch.equal(v, stored[k])
    # resume: one epoch, then a second, equals two epochs at once
    train_stage("mmdmc", "seg", apparel_data, tmp_path / "a", cfg, epochs=2, seed=1, progress=False)
    train_stage("mmdmc", "seg", apparel_data, tmp_path / "b", cfg, epochs=1, seed=1, progress=False)
    train_stage("mmdmc", "seg", apparel_data, tmp_path / "b", cfg, epochs=2, seed=1, progress=False)
    a = load_file(str(tmp_path / "a" / "seg" / "model.safetensors"))
    b = load_file(str(tmp_path / "b" / "seg" / "model.safetensors"))
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert (tmp_path / "b" / "seg" / "loss.csv").read_text().count("\n") == \
        (tmp_path / "a" / "seg" / "loss.csv").read_text().count("\n")


def test_body_weight_term_averages_over_body_vertices_only(apparel_data, run):
    """weights_on="body": the L1 weight term is the mean over body vertices of |w - target|_1 (a naive
    loop), and the targets of apparel vertices do not move it; "all" counts every vertex."""
    st = trainable("mmdmc").stage("body")
    torch.manual_seed(0)
    module = st.build(tiny_config(), None)
    for mode in ("body", "all"):
        cfg = {**tiny_config(), "weights_on": mode}
        ctx = context(apparel_data, run, "body", cfg)
        batch = next(iter(st.batches(cfg, ctx, np.random.default_rng(0))))
        apparel = batch["apparel"].astype(bool)
        assert apparel.any() and (~apparel).any()
        t = {k: torch.as_tensor(v) for k, v in batch.items()}
        got = float(st.loss(module, t, ctx)["weights"].detach())
        w = module(t["points"], t["joints"], t["geo"], t["bone"], t["joint_mask"]).detach().numpy()
        rows = [np.abs(w[b, i] - batch["target_weights"][b, i]).sum() for b in range(len(w)) for i in range(w.shape[1])
                if mode == "all" or not apparel[b, i]]
        assert got == pytest.approx(float(np.mean(rows)), rel=1e-5)
        moved = dict(t, target_weights=torch.where(torch.as_tensor(apparel)[..., None], 1.0 - t["target_weights"],
                                                   t["target_weights"]))
        changed = float(st.loss(module, moved, ctx)["weights"].detach())
        assert (changed == pytest.approx(got, rel=1e-6)) == (mode == "body")
    with pytest.raises(ValueError, match="weights_on"):
        st.loss(module, t, context(apparel_data, run, "body", {**tiny_config(), "weights_on": "apparel"}))


def test_seg_and_body_train_on_a_zoo_never_simulated(apparel_data, tmp_path):
    """With seg_body_clips="kinematic" seg and body read only kinematic clips and the apparel mask: they
    train on the unsimulated zoo, which the default (simulated pairs) refuses with a message naming
    `datagen apparel`."""
    from mimicbench.baselines.mmdmc.data import TrainingData
    from mimicbench.schemas.shards import read_records

    zoo = apparel_data.parent / "zoo"
    data = TrainingData.load(zoo, simulated=False)
    names = [m.name for m in read_records(zoo, "motions")]
    assert sorted(c.name for c in data.clips) == sorted(names) and all(c.simulated is None for c in data.clips)
    with pytest.raises(ValueError, match="datagen apparel"):
        TrainingData.load(zoo)
    for s in ("seg", "body"):
        with pytest.raises(ValueError, match="datagen apparel"):
            train_stage("mmdmc", s, zoo, tmp_path, tiny_config(), epochs=1, seed=0, progress=False)
        path = train_stage("mmdmc", s, zoo, tmp_path, {**tiny_config(), "seg_body_clips": "kinematic"}, epochs=1,
                           seed=0, progress=False)
        assert path.is_file()


def test_attachment_options_train_and_skin_apparel_to_its_chains_body_bone(apparel_data, tmp_path):
    """seg_inputs="bones", apparel_skinning="attachment" and mask_by_piece: every stage trains, the run
    loads with those settings, and with a zero f_d the apparel vertices are LBS of the kinematic pose
    with all their weight on the body bone their nearest apparel chain hangs from (a naive loop)."""
    import copy

    from mimicbench.baselines.mmdmc.apparel import ApparelDynamics
    from mimicbench.baselines.mmdmc.body import skin
    from mimicbench.baselines.mmdmc.data import TrainingData
    from mimicbench.baselines.mmdmc.rig import attachment_bones
    from mimicbench.baselines.mmdmc.method import load_modules
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability, predict, skinning_weights

    cfg = {**tiny_config(), "seg_inputs": "bones", "apparel_skinning": "attachment", "mask_by_piece": True}
    for s in STAGES:
        train_stage("mmdmc", s, apparel_data, tmp_path, cfg, epochs=1, seed=0, progress=False)
    mods = load_modules(tmp_path)
    assert mods.seg.channels == 5 and mods.apparel_skinning == "attachment" and mods.mask_by_piece
    c = next(iter(TrainingData.load(apparel_data).characters.values()))
    clip = TrainingData.load(apparel_data).clips[0]
    zero = copy.copy(mods)
    zero.apparel = ApparelDynamics(cfg["apparel_hidden"], cfg["code"])
    got = predict(zero, c, clip.kinematic[:4], "full")
    assert (apparel_probability(mods.seg, c, True) > 0).all()
    w = skinning_weights(mods.body, c).numpy().copy()
    attach = attachment_bones(c.parents, c.body)
    apparel_bones = np.flatnonzero(~c.body)
    body_column = {int(k): i for i, k in enumerate(np.flatnonzero(c.body))}
    for i, p in enumerate(c.rest.astype(np.float64)):  # nearest apparel bone segment, by brute force
        best, bone = np.inf, -1
        for k in apparel_bones:
            kids = [j for j in apparel_bones if c.parents[j] == k]
            ends = [c.keypoints[j] for j in kids] or [c.keypoints[k]]
            for e in ends:
                a, b = c.keypoints[k].astype(np.float64), np.asarray(e, np.float64)
                ab = b - a
                t = 0.0 if not ab.any() else np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0, 1)
                d = np.linalg.norm(p - (a + t * ab))
                if d < best:
                    best, bone = d, k
        if attach[bone] >= 0:
            w[i] = 0
            w[i, body_column[int(attach[bone])]] = 1
    kin = clip.kinematic[:4]
    expected = skin(torch.as_tensor(c.rest), torch.as_tensor(c.keypoints[c.body]), torch.as_tensor(w),
                    torch.as_tensor(kin[:, c.body])).numpy()
    np.testing.assert_allclose(got, expected, atol=1e-5)


def test_mesh_stretch_edge_term_is_the_relative_stretch_on_mesh_edges_and_a_few_steps_lower_it(apparel_data, run):
    """body_edge_loss="mesh_stretch": every pair of the body batch is a mesh edge of the character (matched
    by rest position), the edge term is the mean of |l_pred / l_truth - 1| over the pairs with both ends on
    body vertices (weights_on="body"; a naive loop), and a few steps on it lower it."""
    from collections import defaultdict

    from mimicbench.baselines.mmdmc.body import skin
    from mimicbench.baselines.mmdmc.data import TrainingData

    cfg = {**tiny_config(), "body_edge_loss": "mesh_stretch", "weights_on": "body", "w_edge": 100.0}
    ctx = context(apparel_data, run, "body", cfg)
    st = trainable("mmdmc").stage("body")
    batch = next(iter(st.batches(cfg, ctx, np.random.default_rng(0))))
    c = next(iter(TrainingData.load(apparel_data).characters.values()))
    at = defaultdict(list)
    for i, p in enumerate(c.rest.tolist()):
        at[tuple(p)].append(i)
    mesh = {tuple(sorted(e)) for e in c.edges.tolist()}
    for b in range(len(batch["rest"])):
        for a, z in batch["edges"][b]:
            pa, pz = at[tuple(batch["rest"][b, a].tolist())], at[tuple(batch["rest"][b, z].tolist())]
            assert any(tuple(sorted((i, j))) in mesh for i in pa for j in pz)
    torch.manual_seed(0)
    module = st.build(cfg, ctx)
    t = {k: torch.as_tensor(v) for k, v in batch.items()}

    def naive() -> float:
        w = module(t["points"], t["joints"], t["geo"], t["bone"], t["joint_mask"]).detach()
        total = 0.0
        for b in range(len(w)):
            pred = ((skin(t["rest"][b], t["rest_joints"][b], w[b], t["transforms"][b]) - t["centre"][b])
                    / t["height"][b]).numpy().astype(np.float64)
            truth = batch["target"][b].astype(np.float64)
            ratios = [np.linalg.norm(pred[i] - pred[j]) / np.linalg.norm(truth[i] - truth[j])
                      for i, j in batch["edges"][b] if not batch["apparel"][b, i] and not batch["apparel"][b, j]]
            total += np.mean(np.abs(np.array(ratios) - 1)) / len(w)
        return total

    first = float(st.loss(module, t, ctx)["edge"].detach())
    assert first == pytest.approx(naive(), rel=1e-4) and first > 0
    assert after_steps(st, module, t, ctx, "edge")["edge"] < first


def test_body_stage_with_the_piece_prior_trains_the_learnt_path(apparel_data, run):
    """body_prior="piece": the body stage hands f_s no piece prior, so it trains the scores that serve
    one-piece meshes (the prior serves wrapped pieces at inference only), and its loss descends."""
    cfg = {**tiny_config(), "body_prior": "piece", "weights_on": "body"}
    ctx = context(apparel_data, run, "body", cfg)
    st = trainable("mmdmc").stage("body")
    torch.manual_seed(0)
    module = st.build(cfg, ctx)
    assert module.prior == "piece"
    batch = next(iter(st.batches(cfg, ctx, np.random.default_rng(0))))
    assert "piece" not in batch
    t = {k: torch.as_tensor(v) for k, v in batch.items()}
    assert descends(st, module, t, ctx)


def _tensors(batch: dict) -> dict:
    return {k: torch.as_tensor(v) if isinstance(v, np.ndarray) else v for k, v in batch.items()}


def test_apparel_rollouts_start_at_rest_at_the_clips_first_frame_as_a_request_does(apparel_data, run):
    """apparel_start="clip": a batch is the whole clip (45 frames, within the burn-in),
    every frame scored, its truth the simulated clip posed with the dataset's weights, and f_d's
    rollout on it is the rollout `predict` answers a request of that clip with (the full pipeline)."""
    from mimicbench.baselines.mmdmc.data import TrainingData, posed
    from mimicbench.baselines.mmdmc.method import load_modules
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability, predict
    from mimicbench.baselines.mmdmc.training import apparel_states

    cfg = {**tiny_config(), "apparel_points": 0, "apparel_start": "clip"}  # every apparel vertex, as at inference
    ctx = context(apparel_data, run, "apparel", cfg)
    batch = next(iter(trainable("mmdmc").stage("apparel").batches(cfg, ctx, np.random.default_rng(0))))
    data = TrainingData.load(apparel_data)
    clip = data.clips[0]
    c = data.characters[clip.character_id]
    mods = load_modules(run)
    idx = np.flatnonzero(apparel_probability(mods.seg, c, mods.mask_by_piece) > mods.threshold)
    assert batch["body"].shape == (1, clip.frames, len(idx), 3) and batch["scored"].all()
    truth = (posed(c, clip.simulated)[:, idx] - c.centre) / c.height
    np.testing.assert_allclose(batch["truth"][0], truth, atol=1e-5)
    with torch.no_grad():
        states, _ = apparel_states(mods.apparel, _tensors(batch), cfg)
    got = states[0].numpy() * c.height + c.centre
    answered = predict(mods, c, clip.kinematic, "full")[:, idx]
    assert np.abs(answered - (batch["body"][0] * c.height + c.centre)).max() > 1e-6  # f_d moved it
    np.testing.assert_allclose(got, answered, atol=2e-5)


def test_window_starts_of_version_6_still_train(apparel_data, run):
    """apparel_start="window": windows of `window` frames after K ground-truth states (a share
    rest_start restarted at rest at the window); a few steps lower the vertex loss."""
    cfg = {**tiny_config(), "apparel_start": "window", "rest_start": 0.0}
    ctx = context(apparel_data, run, "apparel", cfg)
    st = trainable("mmdmc").stage("apparel")
    torch.manual_seed(0)
    module = st.build(cfg, ctx)
    batch = _tensors(next(iter(st.batches(cfg, ctx, np.random.default_rng(0)))))
    assert batch["history"].shape[1] == 3 and batch["truth"].shape[1] == cfg["window"]
    first = {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}
    last = after_steps(st, module, batch, ctx, lr=1e-3, steps=40)
    assert last["vertex"] < first["vertex"], (first, last)
    with pytest.raises(ValueError, match="apparel_start"):
        next(iter(st.batches({**cfg, "apparel_start": "middle"}, ctx, np.random.default_rng(0))))


def test_body_history_model_trains_and_its_batches_are_what_a_request_is_answered_with(apparel_data, run, tmp_path):
    """apparel_model="body_history" (methods version 8): a batch is the clip from its first frame with
    each apparel vertex's frame-bone rotations and rest offset, ``history_frames`` of its frames
    scored; the vertex loss descends along its gradient; and the trained module gives, on the batch, exactly what
    `predict` answers a request of the clip with."""
    import shutil

    from mimicbench.baselines.mmdmc.apparel_history import BodyHistoryApparel
    from mimicbench.baselines.mmdmc.data import TrainingData
    from mimicbench.baselines.mmdmc.method import load_modules
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability, predict
    from mimicbench.baselines.mmdmc.training import apparel_states

    cfg = {**tiny_config(), "apparel_points": 0, "apparel_model": "body_history", "history_hidden": 16,
           "history_frames": 5}
    ctx = context(apparel_data, run, "apparel", cfg)
    st = trainable("mmdmc").stage("apparel")
    torch.manual_seed(0)
    module = st.build(cfg, ctx)
    assert isinstance(module, BodyHistoryApparel)
    batch = _tensors(next(iter(st.batches(cfg, ctx, np.random.default_rng(0)))))
    frames, a = batch["body"].shape[1:3]
    assert batch["rotations"].shape == (1, frames, a, 3, 3) and batch["rest_offset"].shape == (1, a, 3)
    assert int(batch["scored"].sum()) == 5
    assert descends(st, module, batch, ctx, "vertex")
    # through the trainer into a run folder, then inference's own path
    for need in ("seg", "body"):
        shutil.copytree(run / need, tmp_path / need)
    train_stage("mmdmc", "apparel", apparel_data, tmp_path, cfg, epochs=1, seed=0, progress=False)
    mods = load_modules(tmp_path, stages=("seg", "body", "apparel"))
    assert isinstance(mods.apparel, BodyHistoryApparel)
    data = TrainingData.load(apparel_data)
    clip = data.clips[0]
    c = data.characters[clip.character_id]
    idx = np.flatnonzero(apparel_probability(mods.seg, c, mods.mask_by_piece) > mods.threshold)
    with torch.no_grad():
        states, _ = apparel_states(mods.apparel, batch, cfg)
    got = states[0].numpy() * c.height + c.centre
    answered = predict(mods, c, clip.kinematic, "full")[:, idx]
    assert np.abs(answered - (batch["body"][0].numpy() * c.height + c.centre)).max() > 1e-6  # f_d moved it
    np.testing.assert_allclose(got, answered, atol=2e-5)
