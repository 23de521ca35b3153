"""The shipped MMDMC reference on a real MMD model (../shared/assets/mmd/Gene.pmx, ingested):
geodesics over its loose pieces, and a still window that leaves the mesh where it is."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.schemas.shards import read_records


@pytest.mark.slow
def test_gene_pmx_at_rest_stays_at_rest(assets_dir, tmp_path):
    from mimicbench.baselines.mmdmc.geodesic import anchor_vertices, geodesic_distances
    from mimicbench.benchmark.registry import get_method
    from mimicbench.benchmark.request import MotionRequest, Rig
    from mimicbench.cli import main
    from mimicbench.geometry.kinematics import rest_transforms

    assert main(["datagen", "ingest", str(assets_dir / "mmd" / "Gene.pmx"), "--out", str(tmp_path / "gene"),
                 "--quiet"]) == 0
    c = read_records(tmp_path / "gene", "characters")[0]
    body = ~np.asarray(c.apparel_bone_mask, bool)
    v, k = np.asarray(c.vertices), np.asarray(c.keypoints)[body]
    g = geodesic_distances(v, c.faces, k)
    assert g.shape == (len(v), int(body.sum())) and np.isfinite(g).all()
    assert np.all(g[anchor_vertices(v, k), np.arange(len(k))] == 0)
    straight = np.linalg.norm(v[:, None] - v[anchor_vertices(v, k)][None], axis=-1)
    assert np.all(g >= straight - 1e-4)  # a path along the surface is never shorter than the straight line

    rig = Rig(c.character_id, c.category, c.vertices, c.faces, c.keypoints, c.parents, c.weights, c.bone_names)
    still = np.repeat(rest_transforms(np.asarray(c.keypoints))[None], 6, 0).astype(np.float32)
    req = MotionRequest(rig, still, body, 30.0, "gene-still")
    [body_only] = get_method("mmdmc_body_only").transfer_motion([req])
    np.testing.assert_allclose(body_only, np.repeat(v[None], 6, 0), atol=1e-4)  # LBS at rest is the rest mesh
    [full] = get_method("mmdmc").transfer_motion([req])
    assert full.shape == (6, len(v), 3) and np.isfinite(full).all()
    drift = np.linalg.norm(full - v[None], axis=-1).mean() / float(np.ptp(v[:, 1]))
    assert drift < 0.05, f"a still window moved the mesh by {drift:.1%} of its height on average"

    # Gene's front cloak bone has a physics weight bone (錘) 7.5 m below the model: a bone segment to
    # it would run down through the legs. The file's own physics put no apparel below 0.97 m, and
    # f_c must label none of the legs and shoes (below 0.5 m) apparel.
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability

    m = get_method("mmdmc")
    m.setup()
    prep = m._prepare(rig, body)
    assert np.asarray(v)[np.asarray(c.apparel_vertex_mask, bool), 1].min() > 0.9
    labelled = apparel_probability(m.modules.seg, prep, m.modules.mask_by_piece) > m.modules.threshold
    low = np.asarray(v)[:, 1] < 0.5
    assert low.sum() > 4000 and not labelled[low].any(), f"{int(labelled[low].sum())} leg vertices labelled apparel"
