"""PMX/PMD reading and conversion to character records: Gene.pmx against the facts an
independent parser reported (LICENSES.md), field by field against pymeshio (a second parser),
spec-written fixtures (PMX 2.1, UTF-8, additional UVs, QDEF, PMD), and hostile files."""
from __future__ import annotations

import io
from collections import Counter

import numpy as np
import pytest

from mimicbench.datagen.mmd.errors import MMDFormatError
from mimicbench.datagen.mmd.pmd import parse_pmd
from mimicbench.datagen.mmd.pmx import parse_pmx, read_pmx
from mimicbench.datagen.mmd.records import character_from_mmd
from tests.mmd_fixtures import SDEF_C_R0_R1, pmd_bytes, pmx_bytes


@pytest.fixture(scope="module")
def gene_path(assets_dir):
    return assets_dir / "mmd" / "Gene.pmx"


@pytest.fixture(scope="module")
def gene(gene_path):
    return read_pmx(gene_path)


@pytest.fixture(scope="module")
def gene_char(gene, gene_path):
    return character_from_mmd(gene, "assets/Gene", str(gene_path), "train")


def test_gene_counts_match_licenses_md(gene):
    assert gene.format == "PMX 2.0"
    assert len(gene.positions) == 28646 and len(gene.faces) == 47106
    assert Counter(gene.deform.tolist()) == {0: 13552, 1: 10178, 2: 4916}
    assert len(gene.bones) == 224 and sum(b.ik is not None for b in gene.bones) == 6
    assert len(gene.rigid_bodies) == 87 and Counter(r.mode for r in gene.rigid_bodies) == {0: 25, 1: 9, 2: 53}
    assert len(gene.joints) == 92 and gene.num_materials == 13 and gene.num_morphs == 184


def test_gene_agrees_with_pymeshio_field_by_field(gene, gene_path):
    import pymeshio.pmx.reader as reader  # the second parser (the `mmd` extra)
    ref = reader.read(io.BytesIO(gene_path.read_bytes()))
    v3 = lambda v: [v.x, v.y, v.z]  # noqa: E731
    for b, rb in zip(gene.bones, ref.bones):
        assert (b.name, b.name_en, b.parent, b.layer, b.flags) == (rb.name, rb.english_name, rb.parent_index, rb.layer, rb.flag)
        np.testing.assert_array_equal(b.position, np.float32(v3(rb.position)))
        if b.grant_parent >= 0:
            assert (b.grant_parent, np.float32(b.grant_ratio)) == (rb.effect_index, np.float32(rb.effect_factor))
        if b.ik is not None:
            assert (b.ik.target, b.ik.loop, [link.bone for link in b.ik.links]) == (rb.ik.target_index, rb.ik.loop, [link.bone_index for link in rb.ik.link])
    for r, rr in zip(gene.rigid_bodies, ref.rigidbodies):
        assert (r.name, r.bone, r.group, r.mask, r.shape, r.mode) == (rr.name, rr.bone_index, rr.collision_group, rr.no_collision_group & 0xFFFF, rr.shape_type, rr.mode)
        np.testing.assert_array_equal(np.r_[r.size, r.position, r.rotation],
                                      np.float32(v3(rr.shape_size) + v3(rr.shape_position) + v3(rr.shape_rotation)))
        np.testing.assert_array_equal(np.float32([r.mass, r.linear_damping, r.angular_damping, r.restitution, r.friction]),
                                      np.float32([rr.param.mass, rr.param.linear_damping, rr.param.angular_damping, rr.param.restitution, rr.param.friction]))
    for j, rj in zip(gene.joints, ref.joints):
        assert (j.body_a, j.body_b) == (rj.rigidbody_index_a, rj.rigidbody_index_b)
        mine = np.r_[j.position, j.rotation, j.translation_min, j.translation_max, j.rotation_min, j.rotation_max,
                     j.spring_translation, j.spring_rotation]
        theirs = sum((v3(getattr(rj, f)) for f in ("position", "rotation", "translation_limit_min", "translation_limit_max",
                      "rotation_limit_min", "rotation_limit_max", "spring_constant_translation", "spring_constant_rotation")), [])
        np.testing.assert_array_equal(mine, np.float32(theirs))
    np.testing.assert_array_equal(gene.faces.ravel(), np.asarray(ref.indices))
    np.testing.assert_array_equal(gene.positions[::997], np.float32([v3(v.position) for v in ref.vertices[::997]]))


def test_gene_character_record(gene, gene_char):
    c = gene_char
    k = len(c.parents)
    assert k == 224 and all(p < i for i, p in enumerate(c.parents))
    assert c.vertices.shape == (28646, 3) and c.faces.shape == (47106, 3)
    np.testing.assert_allclose(c.weight_values.sum(1), 1.0, atol=1e-5)
    assert c.weight_indices.max() < k and c.category == "humanoid"
    # units and mirror: 前クローク2_2錘 sits at y = -78.3 MMD units; the left foot is at +x, toes at +z
    names = c.bone_names
    assert c.keypoints[names.index("前クローク2_2錘"), 1] == pytest.approx(-78.3 * 0.08, abs=0.01)
    src = gene.bones[[b.name for b in gene.bones].index("左足首")].position
    np.testing.assert_allclose(c.keypoints[names.index("左足首")], src * [0.08, 0.08, -0.08], rtol=1e-6)
    assert c.keypoints[names.index("左足首"), 0] > 0 and c.keypoints[names.index("左つま先ＩＫ"), 2] > c.keypoints[names.index("左足首"), 2]
    # faces face outward after the mirror: triangle normals agree with the file's vertex normals
    n = gene.normals * [1, 1, -1]
    v = c.vertices.astype(np.float64)
    fn = np.cross(v[c.faces[:, 1]] - v[c.faces[:, 0]], v[c.faces[:, 2]] - v[c.faces[:, 0]])
    assert np.mean((fn * n[c.faces].sum(1)).sum(1) > 0) > 0.99
    # every BDEF1 vertex keeps its one bone with weight 1 (bone index mapped through the reorder)
    file_to_new = {f: i for i, f in enumerate(c.meta["mmd"]["file_bone_index"])}
    one = np.flatnonzero(gene.deform == 0)[:50]
    assert [file_to_new[b] for b in gene.weight_bones[one, 0]] == c.weight_indices[one, 0].tolist()
    meta = c.meta["mmd"]
    assert meta["english_names"][names.index("左ひざ")] == "knee_L"
    assert len(meta["ik"]) == 6 and "ik" in meta["bone_roles"][names.index("左足ＩＫ")]
    assert "twist" in meta["bone_roles"][names.index("左腕捩")] and "grant" in meta["bone_roles"][names.index("左目")]


def test_gene_apparel_from_physics(gene_char):
    c = gene_char
    names = c.bone_names
    kinds = {ch["kind"] for ch in c.meta["mmd"]["apparel_chains"]}
    assert {"hair", "skirt", "accessory", "other"} <= kinds
    for name in ("前髪1_2", "すそ1_1", "後クローク1_2", "前髪1End"):
        assert c.apparel_bone_mask[names.index(name)], name
    for name in ("上半身", "頭", "左足", "アホ毛C_IB"):  # body and bone-following (static) bodies
        assert not c.apparel_bone_mask[names.index(name)], name
    cloak = [ch for ch in c.meta["mmd"]["apparel_chains"] if "クローク" in names[ch["root"]]]
    assert cloak and all("クローク" in ch["evidence"] for ch in cloak)
    # the vertex mask follows the weights: a mask vertex has >= half its weight on apparel bones
    w_app = np.where(c.apparel_bone_mask[c.weight_indices], c.weight_values, 0).sum(1)
    np.testing.assert_array_equal(c.apparel_vertex_mask, w_app >= 0.5)
    assert 0 < c.apparel_vertex_mask.sum() < len(c.vertices)


@pytest.mark.parametrize("kw", [dict(), dict(version=2.1, encoding=1, extra_uv=2, qdef=True), dict(extra_uv=4)])
def test_spec_fixture_pmx(kw):
    m = parse_pmx(pmx_bytes(**kw), "fixture.pmx")
    assert m.format == ("PMX 2.1" if kw.get("version") == 2.1 else "PMX 2.0")
    assert m.deform.tolist() == [0, 1, 2, 4 if kw.get("qdef") else 3]
    np.testing.assert_allclose(m.weight_values[1, :2], [0.25, 0.75])
    assert [b.name for b in m.bones] == ["センター", "左足", "左足ＩＫ"]
    assert m.bones[1].grant_rotation and m.bones[1].grant_ratio == pytest.approx(0.5)
    ik = m.bones[2].ik
    assert (ik.target, ik.loop, ik.limit_angle, ik.links[0].bone) == (1, 40, 2.0, 1)
    np.testing.assert_array_equal(ik.links[0].limit_min, [-1, 0, 0])
    rb = m.rigid_bodies[1]
    assert (rb.name, rb.group, rb.shape, rb.mode, rb.mass) == ("髪", 3, 2, 1, 2.0)
    np.testing.assert_allclose(m.joints[0].rotation_min, [-0.1, -0.2, -0.3], rtol=1e-6)
    c = character_from_mmd(m, "fixture", "fixture.pmx", "train")
    # QDEF read as BDEF4, SDEF as BDEF2: vertex 3 has weight 0.75 on bone 1 and 0.25 on bone 2
    dense = c.weights.to_dense()
    np.testing.assert_allclose(dense[3], [0, 0.75, 0.25], atol=1e-6)
    np.testing.assert_allclose(dense[2], [0.5, 0.5, 0], atol=1e-6)
    sdef = c.meta["mmd"]["sdef"]
    assert sdef["skinning"].startswith("BDEF2")
    if kw.get("qdef"):
        assert sdef["vertices"] == [] and sdef["c"] == []
    else:  # the fixture's C, R0, R1 in metres with z mirrored: 0.08 * (x, y, -z)
        assert sdef["vertices"] == [3]
        expected = 0.08 * np.array(SDEF_C_R0_R1).reshape(3, 3) * [1, 1, -1]
        np.testing.assert_allclose([sdef["c"][0], sdef["r0"][0], sdef["r1"][0]], expected, atol=1e-7)


def test_spec_fixture_pmd_agrees_with_pymeshio():
    m = parse_pmd(pmd_bytes(), "fixture.pmd")
    assert [b.name for b in m.bones] == ["センター", "左ひざ", "左足ＩＫ"]
    assert [b.name_en for b in m.bones] == ["center", "knee_L", "leg IK_L"]
    np.testing.assert_allclose(m.weight_values[1, :2], [0.3, 0.7], rtol=1e-6)
    assert m.deform.tolist() == [0, 1, 0] and m.weight_bones[2, 0] == 1
    ik = m.bones[2].ik
    assert ik.limit_angle == pytest.approx(2.0) and ik.links[0].limit_min is not None  # knee: 4 x 0.5 rad, knee limit
    # PMD body positions are offsets from the bone; bone -1 means bone 0 (at y=10), not the origin
    np.testing.assert_allclose(m.rigid_bodies[0].position, [0, 11, 0])
    np.testing.assert_allclose(m.rigid_bodies[1].position, [1, 4, 0])
    import pymeshio.pmd.reader as reader
    ref = reader.read(io.BytesIO(pmd_bytes()))
    assert len(ref.vertices) == len(m.positions) and len(ref.rigidbodies) == 2 and len(ref.joints) == 1
    assert [r.shape_position.y for r in ref.rigidbodies] == [1.0, -1.0]  # stored offsets, as our reader assumed
    np.testing.assert_allclose(m.joints[0].spring_rotation, [21, 22, 23])


@pytest.mark.parametrize("mutate,expected", [
    (lambda b: b"PMD " + b[4:], "wrong magic"),
    (lambda b: b[:200], "truncated"),
    (lambda b: b[:-10], "truncated"),
    (lambda b: b[:14] + b"\x05" + b[15:], "bone index size"),
    (lambda b: b[:9] + b"\x07" + b[10:], "text encoding"),
])
def test_hostile_pmx_named_errors(mutate, expected):
    with pytest.raises(MMDFormatError, match=rf"^bad\.pmx: .*{expected}"):
        parse_pmx(mutate(pmx_bytes()), "bad.pmx")


def test_hostile_pmx_index_nan_encoding_and_huge_count():
    with pytest.raises(MMDFormatError, match="bad.pmx: face vertex: index 9 out of range"):
        parse_pmx(pmx_bytes(bad_index=True), "bad.pmx")
    with pytest.raises(MMDFormatError, match="non-finite"):
        parse_pmx(pmx_bytes(nan=True), "bad.pmx")
    b = bytearray(pmx_bytes(encoding=1))
    start = b.index("テスト".encode())
    b[start] = 0xFF  # not UTF-8
    with pytest.raises(MMDFormatError, match="not valid utf-8 text"):
        parse_pmx(bytes(b), "bad.pmx")
    b = bytearray(pmx_bytes())
    nv_at = b.index(b"\x04\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00")  # vertex count 4, then vertex 0
    b[nv_at:nv_at + 4] = (2 ** 31 - 1).to_bytes(4, "little")
    with pytest.raises(MMDFormatError, match="count of vertices is 2147483647"):
        parse_pmx(bytes(b), "bad.pmx")


def _fuzz(data: bytes, parse, rng, trials: int, region: tuple[int, int] | None = None):
    lo, hi = region or (0, len(data))
    outcomes = Counter()
    for _ in range(trials):
        b = bytearray(data)
        if rng.random() < 0.4:
            b = b[:int(rng.integers(0, len(b)))]
        else:
            for _ in range(int(rng.integers(1, 6))):
                b[int(rng.integers(lo, hi))] ^= int(rng.integers(1, 256))
        try:
            parse(bytes(b), "fuzz.bin")
            outcomes["ok"] += 1
        except MMDFormatError as e:
            assert str(e).startswith("fuzz.bin"), e
            outcomes["error"] += 1
    return outcomes


def test_fuzz_small_files_only_named_errors():
    rng = np.random.default_rng(18)
    for data, parse in ((pmx_bytes(version=2.1, encoding=1, extra_uv=1, qdef=True), parse_pmx), (pmx_bytes(), parse_pmx),
                        (pmd_bytes(), parse_pmd)):
        out = _fuzz(data, parse, rng, 300)
        assert out["error"] > 50


def test_fuzz_gene_only_named_errors(gene_path):
    """A few random truncations and byte flips of the real file (flips after the vertices, where
    counts, indices and text live)."""
    data = gene_path.read_bytes()
    rng = np.random.default_rng(7)
    out = _fuzz(data, parse_pmx, rng, 6, region=(len(data) - 40000, len(data)))
    out += _fuzz(data[:60000], parse_pmx, rng, 4, region=(0, 2000))
    assert out["error"] >= 4


def test_english_names_without_the_dictionary(monkeypatch):
    import sys

    from mimicbench.datagen.mmd.names import english_name

    assert english_name("左ひざ") == ("knee_L", "standard")
    monkeypatch.setitem(sys.modules, "mmd_bone_tools.translate", None)  # not installed
    assert english_name("左ひざ", "knee_L") == ("knee_L", "no-dictionary")
    assert english_name("髪") == ("髪", "no-dictionary")
