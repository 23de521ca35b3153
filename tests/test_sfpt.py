"""SFPT (baselines/sfpt): mesh edges and normals and the mesh EdgeConv against naive loops, the published
widths and size, the decoder reading the target's shape code and the Kabsch fit, the Kabsch-only switch,
handle LBS and Kabsch fits against hand cases, the loss terms against hand values, training steps, the
checkpoint round trip with test-time ARAP, the shipped weights' self-transfer and motions."""
import numpy as np
import pytest
import torch

from mimicbench.baselines.sfpt.handles import deform, fitted_rotations, handle_centres
from mimicbench.geometry.quaternion import quat_from_axis_angle, quat_to_matrix


def grid_mesh(n: int = 5):
    """A bent n x n grid of vertices (n*n, 3) float32 and its triangles (2 (n-1)^2, 3) int64."""
    xs, ys = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    v = np.stack([xs.ravel(), ys.ravel(), 0.3 * np.sin(3 * xs.ravel())], 1).astype(np.float32)
    f = []
    for r in range(n - 1):
        for c in range(n - 1):
            i = r * n + c
            f += [[i, i + 1, i + n], [i + 1, i + n + 1, i + n]]
    return v, np.asarray(f, np.int64)


def test_mesh_edges_are_each_triangle_side_both_ways_plus_self_loops():
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges

    edges = mesh_edges(np.array([[0, 1, 2], [2, 1, 3]]), 5)
    expect = {(0, 1), (1, 2), (0, 2), (1, 3), (2, 3)}
    expect |= {(j, i) for i, j in expect} | {(i, i) for i in range(5)}
    assert sorted(map(tuple, edges.tolist())) == sorted(expect)
    with pytest.raises(ValueError, match="vertex indices"):
        mesh_edges(np.array([[0, 1, 7]]), 5)


def test_vertex_normals_are_the_normalised_sums_of_unit_face_normals():
    from mimicbench.baselines.sfpt.mesh_graph import vertex_normals

    v, f = grid_mesh()
    got = vertex_normals(torch.as_tensor(v, dtype=torch.float64), torch.as_tensor(f)).numpy()
    for i in range(len(v)):
        total = np.zeros(3)
        for tri in f:
            if i in tri:
                n = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]]).astype(np.float64)
                total += n / np.linalg.norm(n)
        np.testing.assert_allclose(got[i], total / np.linalg.norm(total), atol=1e-6)


def test_mesh_edgeconv_is_a_max_over_mesh_neighbours_of_the_mlp_of_centre_and_difference():
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges
    from mimicbench.baselines.sfpt.model import MeshEdgeConv

    torch.manual_seed(0)
    v, f = grid_mesh()
    conv = MeshEdgeConv(4, 6)
    h = torch.randn(len(v), 4)
    out = conv(h, torch.as_tensor(mesh_edges(f, len(v))))
    for i in range(len(v)):
        nbrs = {i} | {int(j) for tri in f if i in tri for j in tri}
        rows = [conv.edge(torch.cat([h[i], h[j] - h[i]])) for j in sorted(nbrs)]
        torch.testing.assert_close(out[i], conv.out(torch.stack(rows).max(0).values), atol=1e-6, rtol=0)


def test_handle_weights_are_rows_summing_to_one_and_read_normals():
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals
    from mimicbench.baselines.sfpt.model import SkinningPredictor

    torch.manual_seed(0)
    v, f = grid_mesh()
    rest, edges = torch.as_tensor(v), torch.as_tensor(mesh_edges(f, len(v)))
    normals = vertex_normals(rest, torch.as_tensor(f))
    pred = SkinningPredictor(4, 12)
    w = pred(rest, normals, edges)
    assert w.shape == (len(v), 12) and float(w.detach().min()) >= 0
    np.testing.assert_allclose(w.sum(-1).detach().numpy(), 1.0, atol=1e-5)
    assert float((pred(rest, -normals, edges) - w).detach().abs().max()) > 1e-6  # the normals are an input


@pytest.mark.parametrize("hidden,code,convs", [(64, 128, [(6, 64), (64, 128), (128, 256)]),
                                               (4, 8, [(6, 4), (4, 8), (8, 16)])])
def test_networks_have_the_published_widths(hidden, code, convs):
    from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer

    model = SkeletonFreePoseTransfer(hidden, 40, code)
    for features in (model.skinning.features, model.encoder.features):
        assert [(c.edge[0].in_features // 2, c.edge[-2].out_features) for c in features.convs] == convs
    assert model.skinning.head[-1].out_features == 40
    assert model.encoder.out[0].out_features == code
    layers = [m for m in model.decoder.net if isinstance(m, torch.nn.Linear)]
    # pose code, target shape code and the 7-number Kabsch fit in; translation and quaternion out
    assert [(m.in_features, m.out_features) for m in layers] == [
        (2 * code + 7, 4 * hidden), (4 * hidden, 2 * hidden), (2 * hidden, 2 * hidden), (2 * hidden, 7)]


def test_relu_init_gives_he_normal_weights_and_zero_biases():
    from mimicbench.baselines.sfpt.model import relu_init

    torch.manual_seed(0)
    layer = torch.nn.Linear(400, 300)
    relu_init(layer)
    assert abs(float(layer.weight.std()) - (2.0 / 400) ** 0.5) < 0.002  # He: std sqrt(2 / fan_in)
    assert float(layer.bias.abs().max()) == 0.0


def test_untrained_networks_tell_vertices_and_handles_apart():
    """PyTorch's default init shrinks the signal over the dozen ReLU layers, so every vertex gets the same
    handle logits (std over vertices about 1e-4) and every handle the same code; the model's init keeps it."""
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals
    from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer

    v, f = grid_mesh(12)
    rest, edges = torch.as_tensor(0.5 * v), torch.as_tensor(mesh_edges(f, len(v)))
    normals = vertex_normals(rest, torch.as_tensor(f))
    torch.manual_seed(0)
    model = SkeletonFreePoseTransfer(16, 40, 64)
    with torch.no_grad():
        logits = model.skinning.head(model.skinning.features(torch.cat([rest, normals], -1), edges))
        code = model.encoder(rest, normals, torch.softmax(logits, -1), edges)
    assert float(logits.std(0).mean()) > 0.01
    assert float(code.std(0).mean() / code.abs().mean()) > 1e-3


def paper_sized_parameters():
    from mimicbench.baselines.sfpt.training import build_sfpt
    from mimicbench.training.registry import trainable

    return sum(p.numel() for p in build_sfpt(trainable("sfpt").config("paper")).parameters())


def test_paper_preset_is_the_published_size():
    assert 1.0e6 < paper_sized_parameters() < 1.3e6  # the published model: about 1.15M


def toy_source():
    """A bent grid at rest and bent further: rest, posed (N, 3), their normals, its edges (E, 2)."""
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges, vertex_normals

    v, f = grid_mesh()
    rest = torch.as_tensor(v)
    posed = rest.clone()
    posed[:, 2] += 0.4 * rest[:, 0] ** 2
    faces = torch.as_tensor(f)
    return rest, posed, (vertex_normals(rest, faces), vertex_normals(posed, faces)), torch.as_tensor(mesh_edges(f, len(v)))


def test_decoder_receives_the_target_shape_code_and_the_kabsch_fit():
    from mimicbench.baselines.sfpt.handles import kabsch_transforms
    from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer

    torch.manual_seed(0)
    model = SkeletonFreePoseTransfer(4, 6, 8).eval()
    rest, posed, normals, edges = toy_source()
    seen = []
    model.decoder.register_forward_hook(lambda mod, args, out: seen.append(args))
    with torch.no_grad():
        w = model.skinning(rest, normals[0], edges)
        code_a, code_b = torch.randn(6, 8), torch.randn(6, 8)
        out_a = model.predict(rest, posed, normals, w, edges, code_a)
        out_b = model.predict(rest, posed, normals, w, edges, code_b)
    torch.testing.assert_close(seen[0][1], code_a, atol=0, rtol=0)
    torch.testing.assert_close(seen[0][2], kabsch_transforms(rest, posed, w), atol=0, rtol=0)
    assert float((out_a - out_b).abs().max()) > 1e-4  # another target, another answer


def test_kabsch_only_switch_returns_the_fit_and_changes_the_answer():
    from mimicbench.baselines.sfpt.handles import kabsch_transforms
    from mimicbench.baselines.sfpt.model import SkeletonFreePoseTransfer

    torch.manual_seed(0)
    model = SkeletonFreePoseTransfer(4, 6, 8).eval()
    rest, posed, normals, edges = toy_source()
    with torch.no_grad():
        w = model.skinning(rest, normals[0], edges)
        code = torch.randn(6, 8)
        fit = model.predict(rest, posed, normals, w, edges, code, kabsch_only=True)
        learned = model.predict(rest, posed, normals, w, edges, code)
    torch.testing.assert_close(fit, kabsch_transforms(rest, posed, w), atol=0, rtol=0)
    assert float((fit - learned).abs().max()) > 1e-3


def test_matrix_to_quat_round_trips_random_rotations():
    from mimicbench.baselines.sfpt.handles import matrix_to_quat_torch

    rng = np.random.default_rng(4)
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    q[:3] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]]  # the identity and two half turns
    got = matrix_to_quat_torch(torch.as_tensor(quat_to_matrix(q))).numpy()
    sign = np.where((got * q).sum(1) < 0, -1.0, 1.0)[:, None]  # a half turn's q and -q are one rotation
    np.testing.assert_allclose(got * sign, q, atol=1e-9)


def test_kabsch_transforms_recover_each_handles_motion():
    from mimicbench.baselines.sfpt.handles import kabsch_transforms

    rng = np.random.default_rng(2)
    v = rng.normal(size=(60, 3))
    w = np.zeros((60, 2))
    w[:30, 0] = w[30:, 1] = 1.0
    q = np.stack([quat_from_axis_angle([0, 1, 0], 0.7), quat_from_axis_angle([1, 0, 1], -2.2)])
    r = quat_to_matrix(q)
    posed = np.where(np.arange(60)[:, None] < 30, v @ r[0].T + 1.0, v @ r[1].T - 2.0)
    got = kabsch_transforms(torch.as_tensor(v), torch.as_tensor(posed), torch.as_tensor(w)).numpy()
    np.testing.assert_allclose(got[0, :3], posed[:30].mean(0) - v[:30].mean(0), atol=1e-9)
    np.testing.assert_allclose(got[1, :3], posed[30:].mean(0) - v[30:].mean(0), atol=1e-9)
    np.testing.assert_allclose(np.abs((got[:, 3:] * q).sum(1)), 1.0, atol=1e-9)


def test_loss_terms_against_hand_values():
    from mimicbench.baselines.sfpt.losses import arap_edges, chamfer, kl, quaternion_loss

    rest = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 2, 0]])
    pred = torch.tensor([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]])
    edges = torch.tensor([[0, 1], [0, 2]])
    assert float(arap_edges(rest, pred, edges)) == pytest.approx((abs(4 - 1) + 0) / 2)
    q = torch.tensor([[1.0, 0, 0, 0]])
    assert float(quaternion_loss(q, -q)) == 0.0 and float(quaternion_loss(q, torch.tensor([[0.0, 1, 0, 0]]))) == 0.5
    a, b = torch.tensor([[0.0, 0, 0], [3, 0, 0]]), torch.tensor([[1.0, 0, 0]])
    assert float(chamfer(a, b)) == pytest.approx((1 + 4) / 2 + 1)
    p, t = torch.tensor([[0.2, 0.8]]), torch.tensor([[0.5, 0.5]])
    assert float(kl(p, t, 0.0)) == pytest.approx((0.5 * np.log(0.5 / 0.2) + 0.5 * np.log(0.5 / 0.8)) / 2)


def test_deform_is_the_weighted_sum_of_each_handles_rigid_motion_about_its_centre():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(20, 3))
    w = rng.random((20, 3))
    w /= w.sum(1, keepdims=True)
    q = np.stack([quat_from_axis_angle(rng.normal(size=3), a) for a in (0.3, -1.1, 2.0)])
    t = rng.normal(size=(3, 3))
    r = quat_to_matrix(q)
    got = deform(torch.as_tensor(v), torch.as_tensor(w), torch.as_tensor(r), torch.as_tensor(t)).numpy()
    for i in range(20):
        expect = np.zeros(3)
        for k in range(3):
            c = (w[:, k:k + 1] * v).sum(0) / w[:, k].sum()
            expect += w[i, k] * (r[k] @ (v[i] - c) + c + t[k])
        np.testing.assert_allclose(got[i], expect, atol=1e-9)


def test_fitted_rotations_recover_each_handles_rotation():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(60, 3))
    w = np.zeros((60, 2))
    w[:30, 0] = w[30:, 1] = 1.0
    r = quat_to_matrix(np.stack([quat_from_axis_angle([0, 1, 0], 0.7), quat_from_axis_angle([1, 0, 1], -2.2)]))
    posed = np.where(np.arange(60)[:, None] < 30, v @ r[0].T + 1.0, v @ r[1].T - 2.0)
    got = fitted_rotations(torch.as_tensor(v)[None], torch.as_tensor(posed)[None], torch.as_tensor(w)[None])[0]
    np.testing.assert_allclose(got.numpy(), r, atol=1e-8)
    np.testing.assert_allclose(handle_centres(torch.as_tensor(v), torch.as_tensor(w)).numpy(),
                               [v[:30].mean(0), v[30:].mean(0)], atol=1e-12)


@pytest.mark.parametrize("term", ["total", "rec", "cross", "cycle"])
def test_each_loss_reaches_the_decoder_and_falls_along_its_gradient(small_zoo, term):
    """A step of norm 1e-4 against the gradient lowers the term by at least half of what the gradient's norm
    predicts (Armijo's condition): a term that a few optimiser steps lower on one machine can rise on another
    (the cycle term is steep), while the first-order decrease holds everywhere."""
    from tests.test_mmdmc_training import after_descent
    from tests.test_npt import first_batch, tiny

    cfg = {**tiny("sfpt"), "residual": False}
    st, module, batch, ctx = first_batch("sfpt", small_zoo, cfg)
    assert set(st.loss(module, batch, ctx)) == {"total", "rec", "cycle", "trans", "cross", "skin", "aug", "fps",
                                                "arap"}
    before, after, norm, decoder_norm = after_descent(st, module, batch, ctx, term, part="decoder.")
    assert decoder_norm > 0.1 * norm, (decoder_norm, norm)
    assert after < before - 0.5 * 1e-4 * norm, (before, after, norm)


def test_checkpoint_round_trips_and_arap_holds_the_rigidly_bound_vertices(small_zoo, tmp_path):
    from mimicbench.baselines.sfpt.method import Sfpt
    from mimicbench.benchmark.request import Rig, TransferRequest
    from tests.test_npt import trained_method
    from mimicbench.schemas.shards import read_records

    method = trained_method(Sfpt, small_zoo, tmp_path / "run")[0]
    plain = Sfpt(checkpoint=tmp_path / "run", arap=False)
    plain.setup("cpu")
    rec = next(iter(read_records(small_zoo, "characters")))
    rig = Rig(rec.character_id, rec.category, rec.vertices, rec.faces, rec.keypoints, rec.parents, rec.weights,
              rec.bone_names)
    posed = rec.vertices + np.float32([0.0, 0.05, 0.0]) * rec.vertices[:, :1]
    request = TransferRequest(rig, posed, rig)
    refined, raw = method.transfer([request])[0], plain.transfer([request])[0]
    assert refined.shape == rec.vertices.shape and np.isfinite(refined).all()
    key = (rec.character_id, len(rec.vertices))
    held = method._refiner.held(f"sfpt/{rec.character_id}/{len(rec.vertices)}", rec.vertices, rec.faces,
                                method._chars[key]["weights"].numpy())
    np.testing.assert_allclose(refined[held], raw[held], atol=1e-5)


def test_shipped_self_transfer_comes_back_close_to_the_posed_source(small_zoo):
    from mimicbench.baselines.sfpt.method import Sfpt
    from tests.test_npt import self_transfer_pmd

    got, identity = self_transfer_pmd(Sfpt(), small_zoo)
    assert got < identity, (got, identity)


def test_motion_requests_transfer_each_frames_body_pose_onto_the_character(small_zoo):
    """Each frame of a motion answer is the transfer request of that frame: the character posed by its
    body bones alone (body_only's weights, LBS) as the source, its own rest mesh as the target."""
    from mimicbench.baselines.body_only import body_weights
    from mimicbench.baselines.sfpt.method import Sfpt
    from mimicbench.benchmark.request import MotionRequest, Rig, TransferRequest
    from mimicbench.geometry.skinning import linear_blend_skinning
    from mimicbench.geometry.weights import SparseWeights
    from mimicbench.schemas.shards import read_records

    rec = next(r for r in read_records(small_zoo, "characters") if r.category == "apparel")
    motion = next(m for m in read_records(small_zoo, "motions") if m.character_id == rec.character_id)
    rig = Rig(rec.character_id, rec.category, rec.vertices, rec.faces, rec.keypoints, rec.parents, rec.weights,
              rec.bone_names)
    frames = np.asarray(motion.transforms, np.float32)[:5]
    body = ~np.asarray(rec.apparel_bone_mask, bool)
    method = Sfpt()
    out = method.transfer_motion([MotionRequest(rig, frames, body, 30.0)])[0]
    assert out.shape == (5, len(rec.vertices), 3) and np.isfinite(out).all()
    weights = SparseWeights.from_dense(body_weights(rig, body))
    for f in (0, 4):
        posed = linear_blend_skinning(rig.vertices, rig.keypoints, weights, frames[f])
        single = method.transfer([TransferRequest(rig, posed, rig)])[0]
        np.testing.assert_allclose(out[f], single, atol=1e-4)
