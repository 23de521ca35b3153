"""Rendering through Blender: cameras against hand-computed values, silhouettes against the
orthographic projection worked out by hand, the render command and the contact sheet."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.datagen.render.camera import MARGIN, fit_camera
from mimicbench.datagen.render.panel import Panel
from mimicbench.datagen.render.render import compose_sheet


def box(lo, hi):
    """(8, 3) vertices and (12, 3) outward triangles of an axis-aligned box."""
    lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f, np.int32)


def test_fit_camera_hand_computed():
    # Looking straight down -Z at the unit cube: right = +X, up = +Y, the projection is 1 x 1.
    v, _ = box((0, 0, 0), (1, 1, 1))
    cam = fit_camera(v, 200, 100, direction=(0, 0, 1))
    np.testing.assert_allclose(cam.right, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(cam.up, [0, 1, 0], atol=1e-12)
    # Landscape 2:1 image: the wider side spans max(w, h * 2) = 2 m, times the margin.
    assert cam.ortho_scale == pytest.approx(2.0 * MARGIN)
    np.testing.assert_allclose(cam.location, [0.5, 0.5, 1.0 + 1.0])  # in front by the extent
    px = cam.project(v, 200, 100)
    # 200 px span 2.3 m: the 1 m cube is 86.96 px wide, centred on the image centre (100, 50).
    half = 0.5 * 200 / (2.0 * MARGIN)
    assert px[:, 0].min() == pytest.approx(100 - half) and px[:, 0].max() == pytest.approx(100 + half)
    assert px[:, 1].min() == pytest.approx(50 - half) and px[:, 1].max() == pytest.approx(50 + half)
    assert cam.clip_end > 2.0 and 0 < cam.clip_start < 0.01


def test_fit_camera_frames_every_point():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(500, 3)) * [0.2, 1.5, 0.4] + [3, 1, -2]
    for w, h in ((320, 320), (400, 200), (200, 400)):
        px = fit_camera(pts, w, h).project(pts, w, h)
        assert px[:, 0].min() > 0 and px[:, 0].max() < w and px[:, 1].min() > 0 and px[:, 1].max() < h
        # fitted, not loose: the tighter side is within the margin
        assert max(np.ptp(px[:, 0]) / w, np.ptp(px[:, 1]) / h) == pytest.approx(1 / MARGIN, rel=1e-6)


def test_shared_frame_keeps_offsets_and_survives_an_outlier():
    from mimicbench.datagen.render.render import GROUP_CAP, frame_panels

    ref = box((0, 0, 0), (1, 1, 1))
    near = box((0.1, 0, 0), (1.1, 1, 1))  # 10 cm off: stays in the shared frame, offset visible
    far = box((50, 0, 0), (51, 1, 1))  # 50 m off: re-centred, with a note
    huge = box((0, 0, 0), (30, 30, 30))  # exploded: its own zoom, the others keep theirs
    panels = [Panel(*m, f"p{i}", frame="t") for i, m in enumerate((ref, near, far, huge))]
    framed = frame_panels(panels, 100, 100)
    scales = [c.ortho_scale for c, _ in framed]
    assert scales[0] == scales[1] == scales[2] == pytest.approx(GROUP_CAP * fit_camera(ref[0], 100, 100).ortho_scale)
    np.testing.assert_allclose(framed[0][0].location @ framed[0][0].right, framed[1][0].location @ framed[1][0].right)
    assert framed[1][1] == "" and framed[2][1] == "re-centred: 50.00 m off" and framed[3][1].startswith("zoomed out")


def test_panel_rejects_bad_input():
    v, f = box((0, 0, 0), (1, 1, 1))
    with pytest.raises(ValueError, match=r"expected vertices of shape \(N, 3\)"):
        Panel(v[:, :2], f)
    with pytest.raises(ValueError, match="face indices must lie in"):
        Panel(v, f + 8)
    with pytest.raises(ValueError, match="NaN"):
        Panel(v * np.nan, f)
    with pytest.raises(ValueError, match="unknown role"):
        Panel(v, f, role="villain")
    assert Panel(v, f, role="prediction").colour == (0.93, 0.58, 0.25)


def test_compose_sheet_layout():
    img = np.zeros((40, 50, 4), np.uint8)
    img[10:30, 10:40] = (255, 0, 0, 255)
    sheet = compose_sheet([img, img, "boom"], ["a", "b\nsecond line", "c"], columns=2, width=50, height=40)
    assert sheet.size[0] == 100
    arr = np.asarray(sheet)
    assert (arr == (255, 0, 0)).all(axis=2).sum() == 2 * 20 * 30  # both tiles pasted, unscaled
    with pytest.raises(ValueError, match="as many labels as images"):
        compose_sheet([img], ["a", "b"])


def _alpha_mask(img):
    return np.asarray(img)[..., 3] > 127


@pytest.mark.blender
def test_render_matches_orthographic_projection():
    """Silhouettes from Blender against the projection worked out here: the area of a unit cube's
    silhouette seen along unit d is |dx| + |dy| + |dz| m²; a small cube sharing the big one's
    frame lands where the camera's own projection puts it."""
    from mimicbench.datagen.render.camera import VIEW_DIRECTION
    from mimicbench.datagen.render.render import frame_panels, render_panels

    big = box((-0.5, 0, -0.5), (0.5, 1, 0.5))
    small = box((0.3, 0.8, 0.3), (0.5, 1.0, 0.5))
    tall = box((0, 0, 0), (0.2, 1.0, 0.2))
    panels = [Panel(*big, "big", frame="shared"), Panel(*small, "small", frame="shared"), Panel(*tall, "tall")]
    size = 240
    images = render_panels(panels, size, size)
    assert all(isinstance(i, np.ndarray) and i.shape == (size, size, 4) for i in images), images
    d = VIEW_DIRECTION / np.linalg.norm(VIEW_DIRECTION)
    cams = [c for c, _ in frame_panels(panels, size, size)]
    assert cams[0].ortho_scale == cams[1].ortho_scale  # one frame: the small cube reads at the big one's scale
    cam = cams[1]
    px_per_m = size / cams[0].ortho_scale
    expected = np.abs(d).sum() * px_per_m ** 2
    assert _alpha_mask(images[0]).sum() == pytest.approx(expected, rel=0.05)
    ys, xs = np.nonzero(_alpha_mask(images[1]))
    centre = cam.project(small[0].mean(axis=0, keepdims=True), size, size)[0]
    assert abs(xs.mean() - centre[0]) < 2 and abs(ys.mean() - centre[1]) < 2
    ys, xs = np.nonzero(_alpha_mask(images[2]))
    assert np.ptp(ys) > 2 * np.ptp(xs)  # Y up in the data is up in the picture


@pytest.mark.blender
def test_render_command_and_contact_sheet(small_zoo, tmp_path, capsys):
    import shutil

    from PIL import Image

    from mimicbench.datagen.zoo.card import add_contact_sheet
    from mimicbench.cli import main

    out = tmp_path / "walk.png"
    assert main(["render", str(small_zoo), "zoo/humanoid-0000", "--motion", "walk", "--frame", "10",
                 "--out", str(out), "--size", "200"]) == 0
    arr = np.asarray(Image.open(out).convert("RGB")).astype(float)
    body = (arr < 250).any(axis=2)
    assert 0.03 < body.mean() < 0.9 and arr.std() > 20  # a figure, not a blank or a filled frame
    assert main(["render", str(small_zoo), "zoo/humanoid-0000", "--motion", "nope", "--out", str(out)]) == 2
    assert "has no motion 'nope'; its motions: walk" in capsys.readouterr().err

    data = tmp_path / "zoo"
    shutil.copytree(small_zoo, data)
    first = add_contact_sheet(data)
    assert first["error"] is None and first["path"].exists()
    again = add_contact_sheet(data)
    card = (data / "CARD.md").read_text()
    assert card.count("card/contact_sheet.png") == 1 and card.startswith("# mimicbench procedural zoo")
    sheet = np.asarray(Image.open(again["path"]).convert("RGB")).astype(float)
    assert sheet.shape[0] > 400 and sheet.std() > 20
