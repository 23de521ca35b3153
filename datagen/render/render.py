"""Render panels through Blender in one child process, and lay them out as a labelled sheet.

:func:`render_panels` writes the meshes and a job file, runs ``python -m
mimicbench.datagen.render.blender_child`` with a timeout (the ingest's pattern: a crash or a hang in
Blender becomes an error here, never a dead parent), and reads the panels back as RGBA images.
:func:`render_sheet` adds the layout: a grid of panels, each with its label above it, on white.
"""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from mimicbench.datagen.render.camera import OrthoCamera, fit_camera
from mimicbench.datagen.render.panel import Panel

PANEL_PX = 320


class RenderError(RuntimeError):
    """Blender could not render a job (bpy missing, the child crashed or timed out)."""


GROUP_ROOM = 1.25  # a shared frame is this much larger than its largest member, so offsets show
GROUP_CAP = 2.5  # ... but at most this many times the frame of its first member (the reference)


def _bbox_centre(v: np.ndarray) -> np.ndarray:
    return (v.min(axis=0) + v.max(axis=0)) / 2


def frame_panels(panels: Sequence[Panel], width: int, height: int) -> list[tuple[OrthoCamera, str]]:
    """A camera per panel, and a note ("" or why it deviates from its group's frame).

    Panels sharing a ``frame`` key share one scale and one centre, those of the reference (the
    member marked ``reference``, else the first; e.g. the ground truth or the target at rest), so a prediction's offset and size read against it. The
    shared scale fits the largest member with room to spare, capped at :data:`GROUP_CAP` times
    the reference's, so one exploded prediction does not shrink the others to dots. A member
    that would leave the frame is re-centred on itself (its note gives the offset in metres), and
    one larger than the cap gets its own scale (its note says how much it was zoomed out).
    """
    keys = [p.frame if p.frame is not None else f"__panel{i}" for i, p in enumerate(panels)]
    own = [fit_camera(p.vertices, width, height) for p in panels]
    out: list = [None] * len(panels)
    for key in dict.fromkeys(keys):
        members = [i for i, k in enumerate(keys) if k == key]
        ref = next((i for i in members if panels[i].reference), members[0])
        if len(members) == 1:
            out[ref] = (own[ref], "")
            continue
        scale = min(GROUP_ROOM * max(own[i].ortho_scale for i in members), GROUP_CAP * own[ref].ortho_scale)
        for i in members:
            v = panels[i].vertices
            cam = fit_camera(v, width, height, scale=scale, centre=own[ref].location)
            px = cam.project(v, width, height)
            if px[:, 0].min() >= 0 and px[:, 0].max() <= width and px[:, 1].min() >= 0 and px[:, 1].max() <= height:
                out[i] = (cam, "")
            elif own[i].ortho_scale <= scale:
                off = float(np.linalg.norm(_bbox_centre(v) - _bbox_centre(panels[ref].vertices)))
                out[i] = (fit_camera(v, width, height, scale=scale), f"re-centred: {off:.2f} m off")
            else:
                out[i] = (own[i], f"zoomed out {own[i].ortho_scale / scale:.1f}x")
    return out


def _camera_spec(c: OrthoCamera) -> dict:
    return {"location": c.location.tolist(), "right": c.right.tolist(), "up": c.up.tolist(), "back": c.back.tolist(),
            "ortho_scale": c.ortho_scale, "clip_start": c.clip_start, "clip_end": c.clip_end}


def with_notes(labels: Sequence[str], notes: Sequence[str]) -> list[str]:
    """Labels with each framing note (from :func:`frame_panels`) as a last line in brackets."""
    return [f"{label}\n({note})" if note else label for label, note in zip(labels, notes)]


def render_panels(panels: Sequence[Panel], width: int = PANEL_PX, height: int = PANEL_PX,
                  timeout: float | None = None) -> list[np.ndarray | str]:
    """Render each panel with Blender (Workbench), all in one child process.

    Args:
        panels: the meshes; panels sharing a ``frame`` key share a camera (see :func:`frame_panels`).
        width, height: pixels of each panel.
        timeout: seconds for the whole job (default 120 + 15 a panel).

    Returns:
        Per panel, an (height, width, 4) uint8 RGBA image (transparent background), or a string
        ``render failed: ...`` saying why that panel failed.

    Raises:
        RenderError: bpy is not installed, or the Blender process crashed or timed out.
    """
    if not panels:
        return []
    if importlib.util.find_spec("bpy") is None:
        raise RenderError("rendering needs Blender's Python module bpy; install the `blender` extra "
                          "(pip install 'mimicbench[blender]', Python 3.11)")
    timeout = 120.0 + 15.0 * len(panels) if timeout is None else timeout
    cams = [_camera_spec(c) for c, _ in frame_panels(panels, width, height)]
    with tempfile.TemporaryDirectory(prefix="mimicbench-render-") as tmp:
        tmp = Path(tmp)
        arrays = {}
        for i, p in enumerate(panels):
            arrays[f"v{i}"], arrays[f"f{i}"] = p.vertices, p.faces
        np.savez(tmp / "meshes.npz", **arrays)
        job = {"meshes": str(tmp / "meshes.npz"), "width": width, "height": height, "cameras": cams,
               "panels": [{"mesh": i, "colour": list(p.colour), "camera": i, "out": str(tmp / f"panel{i}.png")}
                          for i, p in enumerate(panels)]}
        job_file = tmp / "job.json"
        job_file.write_text(json.dumps(job))
        start = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, "-m", "mimicbench.datagen.render.blender_child", str(job_file)],
                                  capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired as exc:
            raise RenderError(f"Blender render of {len(panels)} panels timed out after {timeout:g} s") from exc
        result_file = tmp / "job.result.json"
        if not result_file.exists():
            tail = (proc.stderr or proc.stdout or "").strip().splitlines()[-1:] or ["no output"]
            raise RenderError(f"Blender process ended with code {proc.returncode} after "
                              f"{time.perf_counter() - start:.0f} s ({tail[0][:200]})")
        result = json.loads(result_file.read_text())
        if result["status"] != "ok":
            raise RenderError(f"Blender render failed: {result['reason']}")
        from PIL import Image

        out = []
        for i, status in enumerate(result["panels"]):
            png = tmp / f"panel{i}.png"
            if status["ok"] and png.exists():
                out.append(np.asarray(Image.open(png).convert("RGBA")))
            else:
                out.append(f"render failed: {status['error'] or 'no image written'}")
        return out


def _font(size: int):
    from matplotlib import font_manager
    from PIL import ImageFont

    return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), size)


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)[:8])


def compose_sheet(images: Sequence[np.ndarray | str], labels: Sequence[str], columns: int | None = None,
                  title: str | None = None, width: int = PANEL_PX, height: int = PANEL_PX):
    """Lay out rendered panels in a grid, each labelled above, on white; returns a PIL RGB image.

    Args:
        images: per panel an (H, W, 4) uint8 RGBA image, or a string drawn as text in a red box
            (why there is no picture).
        labels: per panel its label (newlines allowed).
        columns: panels a row (default: all in one row).
        title: optional line above the grid.
    """
    from PIL import Image, ImageDraw

    n = len(images)
    if n == 0 or len(labels) != n:
        raise ValueError(f"compose_sheet: expected as many labels as images (> 0), got {len(labels)} and {n}")
    cols = min(n, columns or n)
    rows = -(-n // cols)
    font, title_font = _font(max(11, width // 24)), _font(max(13, width // 18))
    line_h = int(font.size * 1.3)
    label_h = line_h * max(s.count("\n") + 1 for s in labels) + 6
    title_h = int(title_font.size * 1.8) if title else 0
    sheet = Image.new("RGB", (cols * width, title_h + rows * (label_h + height)), "white")
    draw = ImageDraw.Draw(sheet)
    if title:
        draw.text((8, title_h // 4), title, fill=(20, 20, 20), font=title_font)
    for i, (img, label) in enumerate(zip(images, labels)):
        x, y = (i % cols) * width, title_h + (i // cols) * (label_h + height)
        for j, line in enumerate(label.split("\n")):
            tw = draw.textlength(line, font=font)
            draw.text((x + max(4, (width - tw) / 2), y + 3 + j * line_h), line, fill=(30, 30, 30), font=font)
        if isinstance(img, str):
            draw.rectangle((x + 4, y + label_h, x + width - 4, y + label_h + height - 4), outline=(200, 60, 60))
            draw.multiline_text((x + 10, y + label_h + 10), _wrap(img, max(12, width // (font.size // 2 + 1))),
                                fill=(200, 60, 60), font=font)
        else:
            tile = Image.fromarray(np.asarray(img, np.uint8), "RGBA")
            if tile.size != (width, height):
                tile = tile.resize((width, height))
            sheet.paste(tile, (x, y + label_h), tile)
    return sheet


def render_sheet(panels: Sequence[Panel], out_png, columns: int | None = None, title: str | None = None,
                 width: int = PANEL_PX, height: int = PANEL_PX, timeout: float | None = None) -> Path:
    """Render ``panels`` (one Blender process) and write them as one labelled PNG; returns its path.

    Raises:
        RenderError: see :func:`render_panels`.
    """
    images = render_panels(panels, width, height, timeout)
    notes = [note for _, note in frame_panels(panels, width, height)]
    sheet = compose_sheet(images, with_notes([p.label for p in panels], notes), columns, title, width, height)
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    sheet.save(tmp)
    tmp.replace(out)
    return out
