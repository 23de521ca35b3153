"""Rendered strips for the leaderboard: for a few sampled cases of each protocol, the posed source,
the target's ground truth (where the protocol has one), every method's prediction, and for cycle
protocols the source each method returned.

Predictions come from the sample store (:mod:`mimicbench.benchmark.samples`); rest meshes, faces and the
case's transforms from the dataset the run used (``run.json``). Every panel of every strip is
rendered in one Blender process (:func:`mimicbench.datagen.render.render_panels`), then each strip is laid
out as one labelled PNG. Colours follow :data:`mimicbench.datagen.render.ROLE_COLOURS` (source blue, ground
truth green, prediction orange, returned purple, rest grey); panels on the same character share a
camera, so a prediction's offset from the truth stays visible.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from mimicbench.benchmark.results import read_result_records
from mimicbench.benchmark.samples import SAMPLES_DIR, read_sample, sample_rank
from mimicbench.datagen.render.panel import Panel
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.columns import table_to_records
from mimicbench.schemas.shards import has_table, read_records, read_table
from mimicbench.schemas.tables import record_type

STRIPS_PER_PROTOCOL = 3
PANEL_PX = 220


@dataclass
class Strip:
    """One picture: panels (a :class:`Panel`, or a string saying why there is none), in rows of
    ``columns``, with a title."""

    protocol: str
    case_id: str
    title: str
    columns: int
    items: list = field(default_factory=list)

    @property
    def file_stem(self) -> str:
        return f"{self.protocol}-{sample_rank(self.case_id)[:10]}"


def find_dataset(results, run_info: dict, methods_info: dict) -> Path | None:
    """The dataset folder the run used: ``run.json``'s or a ``meta.json``'s ``dataset``, as given,
    or relative to the results folder or one of its parents (a run started elsewhere); None when
    none of them holds a manifest."""
    names = [run_info.get("dataset")] + [m.get("dataset") for m in methods_info.values()]
    here = Path(results).resolve()
    for name in [n for n in names if isinstance(n, str) and n]:
        for candidate in [Path(name)] + [base / name for base in (here, *here.parents)]:
            if (candidate / "manifest.json").exists():
                return candidate
    return None


def sampled_case_ids(results, protocol: str, method_versions) -> list[str]:
    """Case IDs with a stored sample for ``protocol``, most methods first, then by sample rank."""
    count: dict[str, int] = {}
    for method, version in method_versions:
        folder = Path(results) / method / version / SAMPLES_DIR / protocol
        for f in folder.glob("*.npz") if folder.is_dir() else ():
            with np.load(f) as d:
                if "case_id" in d.files:
                    cid = str(d["case_id"])
                    count[cid] = count.get(cid, 0) + 1
    return sorted(count, key=lambda c: (-count[c], sample_rank(c)))


def _characters(dataset, ids) -> dict:
    t = read_table(dataset, "characters")
    t = t.filter(pc.is_in(t["character_id"], value_set=pa.array(sorted(ids), pa.string())))
    return {c.character_id: c for c in table_to_records(t, record_type("characters"))}


def _posed(char, transforms) -> np.ndarray:
    """``char`` posed by a case's transforms: (K, 7), or a window (F*K, 7) of which the middle frame is
    shown, the frame a windowed protocol (apparel) keeps as its sample."""
    window = np.asarray(transforms, np.float32).reshape(-1, len(char.parents), 7)
    return linear_blend_skinning(np.asarray(char.vertices, np.float32), np.asarray(char.keypoints, np.float32),
                                 char.weights, window[len(window) // 2]).astype(np.float32)


def _fmt(value) -> str:
    return "—" if value is None else f"{value:.2f}"


def build_strips(results, agg: dict, per_protocol: int = STRIPS_PER_PROTOCOL) -> tuple[list[Strip], str | None]:
    """The strips to render, and None or a note saying why there are none.

    Args:
        results: results folder.
        agg: :func:`mimicbench.benchmark.aggregate.aggregate` of it (method order, headline metrics).
    """
    dataset = find_dataset(results, agg.get("run", {}), agg.get("methods", {}))
    if dataset is None:
        return [], f"no pictures: the run's dataset ({agg.get('run', {}).get('dataset')!r}) was not found"
    strips = []
    for protocol, matrix in agg["matrix"].items():
        order = [(r["method"], r["version"]) for r in matrix["rows"]]
        ids = sampled_case_ids(results, protocol, order)[:per_protocol]
        if not ids or not has_table(dataset, "cases", protocol):
            continue
        cases = {c.case_id: c for c in read_records(dataset, "cases", protocol) if c.case_id in set(ids)}
        chars = _characters(dataset, {x for c in cases.values() for x in (c.source_id, c.target_id)})
        head = matrix["headline"]
        scores = {}
        for mv in order:
            rows = read_result_records(Path(results) / mv[0] / mv[1])
            scores[mv] = {r.case_id: r for r in rows if r.protocol == protocol}
        for cid in ids:
            case = cases.get(cid)
            if case is None or case.source_id not in chars or case.target_id not in chars:
                continue
            src, tgt = chars[case.source_id], chars[case.target_id]
            cycle = case.target_transforms is None
            windowed = len(np.asarray(case.source_transforms).reshape(-1, 7)) > len(src.parents)
            # apparel: the source rows hold burn-in frames before the window; its last rows are the window
            shown = case.source_transforms[-len(case.target_transforms):] if windowed else case.source_transforms
            items = [Panel(_posed(src, shown), src.faces,
                           f"posed source\n{src.character_id}", "source", frame=f"{cid}/source")]
            if not cycle:
                items.append(Panel(_posed(tgt, case.target_transforms), tgt.faces,
                                   f"ground truth\n{tgt.character_id}", "ground_truth", frame=f"{cid}/target"))
            returned = [Panel(tgt.vertices, tgt.faces, f"target at rest\n{tgt.character_id}", "rest",
                              frame=f"{cid}/target", reference=True)] if cycle else []
            for method, version in order:
                sample = read_sample(Path(results) / method / version, protocol, cid)
                row = scores[(method, version)].get(cid)
                value = getattr(row, head, None) if row is not None else None
                status = "not run" if row is None else (row.error or row.status)
                fwd = sample.get("forward")
                if cycle:
                    items.append(Panel(fwd, tgt.faces, f"{method}: forward\non {tgt.character_id}", "prediction",
                                       frame=f"{cid}/target") if fwd is not None else f"{method}: no prediction ({status})")
                    back = sample.get("returned")
                    returned.append(Panel(back, src.faces, f"{method}: returned\n{head} {_fmt(value)}", "returned",
                                          frame=f"{cid}/source") if back is not None
                                    else f"{method}: no return ({status})")
                else:
                    items.append(Panel(fwd, tgt.faces, f"{method}\n{head} {_fmt(value)}", "prediction",
                                       frame=f"{cid}/target") if fwd is not None else f"{method}: no prediction ({status})")
            title = f"{protocol}: {cid}" + ("   (middle frame of the window)" if windowed else "") + ("   (top: forward leg on the target; bottom: the cycle's return on "
                                            "the source)" if cycle else "")
            strips.append(Strip(protocol, cid, title, len(items), items + returned))
    return strips, None if strips else "no pictures: no stored samples (re-run `bench run` to keep some)"


def render_strips(strips: list[Strip], out_dir, panel_px: int = PANEL_PX, timeout: float | None = None) -> list[dict]:
    """Render every strip (one Blender process for all) into ``out_dir/<protocol>-<digest>.png``.

    Returns:
        Per strip ``{"protocol", "case_id", "title", "path"}``.

    Raises:
        mimicbench.datagen.render.RenderError: Blender is missing, crashed or timed out.
    """
    from mimicbench.datagen.render.render import compose_sheet, frame_panels, render_panels, with_notes

    panels = [p for s in strips for p in s.items if isinstance(p, Panel)]
    images = iter(render_panels(panels, panel_px, panel_px, timeout))
    notes = iter(note for _, note in frame_panels(panels, panel_px, panel_px))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    done = []
    for s in strips:
        imgs = [next(images) if isinstance(p, Panel) else p for p in s.items]
        labels = [with_notes([p.label], [next(notes)])[0] if isinstance(p, Panel) else "" for p in s.items]
        sheet = compose_sheet(imgs, labels, s.columns, s.title, panel_px, panel_px)
        path = out / f"{s.file_stem}.png"
        sheet.save(path)
        done.append({"protocol": s.protocol, "case_id": s.case_id, "title": s.title, "path": path})
    return done
