"""Write the leaderboard: Markdown, CSV, JSON and a self-contained HTML page with plots and pictures.

Per protocol: first the ranking (each method's mean of the headline column and of the forward
scores present, with 95% intervals from a bootstrap clustered by (source, target) pair, the paired
difference against a reference method, ranks with ties, whether the method reads the rig; cct sorts
by ``semantic_deg``), then the method x category matrix of the headline metric (with an ``all``
column and a "missing / failed / not supported" column), a plot per category (log axis when one category is
far off), the summary of every metric, and rendered strips of a few sampled cases (see
:mod:`mimicbench.benchmark.leaderboard_strips`). Then each method's licence, citation and provenance.
Files: ``leaderboard.md``, ``.csv`` (one row per protocol and method), ``leaderboard_matrix.csv``
(one row per protocol, method and category), ``leaderboard_ranking.csv`` (one row per protocol,
column and method: mean, interval, difference, rank), ``.json`` (:func:`mimicbench.benchmark.aggregate.aggregate`),
``.html`` (images embedded), and ``leaderboard_files/`` (the same images as PNG files, which the
Markdown links to).
"""
from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from pathlib import Path

from mimicbench.benchmark.aggregate import ALL, DEFAULT_REFERENCE, aggregate
from mimicbench.benchmark.provenance import check_results_provenance
from mimicbench.schemas.manifest import atomic_write_bytes

FILES_DIR = "leaderboard_files"
COUNT_COLUMNS = (("cases", "cases"), ("ok", "ok"), ("failed", "failed"), ("missing", "missing"),
                 ("not_supported", "not supported"))
STATUS_HEADER = "missing / failed / not supported"


def _fmt(value, key: str = "") -> str:
    if value is None or isinstance(value, float) and not math.isfinite(value):
        return "—"  # never "nan": a non-finite mean is no average
    if isinstance(value, float):
        return f"{value:.4f}" if key == "seconds_per_case" else f"{value:.3f}"
    return str(value)


def _status(row: dict) -> str:
    refused = row.get("invalid", 0)
    if row["missing"] == row["failed"] == row["not_supported"] == refused == 0:
        return "complete"
    text = f"{row['missing']} / {row['failed']} / {row['not_supported']}"
    return text + (f" + {refused} rows refused" if refused else "")


def refused_lines(agg: dict, limit: int = 50) -> list[str]:
    """Markdown lines listing the result rows that were not averaged, with the reason."""
    refused = agg.get("refused") or []
    if not refused:
        return []
    lines = ["### Rows not averaged", "", f"{len(refused)} result rows failed the checks (benchmark/result_checks.py) "
             "and were left out; their methods get no average.", "", "| method | protocol | case | reason |",
             "|---|---|---|---|"]
    for r in refused[:limit]:
        lines.append(f"| {r['method']} v{r['version']} | {r['protocol']} | {_md_cell(r['case_id'] or '—')} "
                     f"| {_md_cell(_one_line(r['reason']))} |")
    if len(refused) > limit:
        lines.append(f"| … | | | {len(refused) - limit} more in leaderboard.json |")
    return lines + [""]


def _one_line(text, limit: int = 120) -> str:
    text = " ".join(str(text or "").split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _md_cell(text) -> str:
    return str(text).replace("|", "\\|")


def _short_fingerprints(fps, prefix: str = "") -> str:
    """``name digest[:12]`` pairs, nested dicts flattened (``cases.h2h``), nulls left out."""
    if not fps:
        return "—"
    if not isinstance(fps, dict):
        return str(fps)[:12]
    parts = []
    for k, v in sorted(fps.items()):
        if isinstance(v, dict):
            parts.append(_short_fingerprints(v, f"{prefix}{k}."))
        elif v is not None:
            parts.append(f"{prefix}{k} {str(v)[:12]}")
    return ", ".join(p for p in parts if p and p != "—") or "—"


def _title(agg: dict, protocol: str) -> str:
    title = agg.get("titles", {}).get(protocol)
    return f"{protocol}: {title}" if title and title != protocol else protocol


def _signed(value) -> str:
    return "—" if value is None else f"{value:+.3f}"


def _interval(cell: dict) -> str:
    """``mean [lo, hi]``, or ``—``."""
    if cell.get("mean") is None:
        return "—"
    return f"{_fmt(cell['mean'])} [{_fmt(cell['lo'])}, {_fmt(cell['hi'])}]"


def _difference(cell: dict, is_reference: bool) -> str:
    """``+diff [lo, hi]`` against the reference, ``reference`` on its own row, ``—`` without one."""
    if is_reference:
        return "reference"
    if cell.get("diff") is None:
        return "—"
    return f"{_signed(cell['diff'])} [{_signed(cell['diff_lo'])}, {_signed(cell['diff_hi'])}]"


def _rank(cell: dict) -> str:
    """``=2`` for a shared (tied) rank, ``2`` for a rank of its own, ``—`` for none."""
    r = cell.get("rank")
    return "—" if r is None else f"={r}" if cell.get("tied") else str(r)


def _ref_name(ranking: dict) -> str:
    ref = ranking.get("reference")
    return ref.replace("/", " v", 1) if ref else "—"


def ranking_notes(ranking: dict) -> list[str]:
    """Plain-text notes under a ranking table: how it is read, the unscored cases, the reference."""
    sort = ranking["sort"]
    better = "lower is better" if ranking["lower_is_better"][sort] else "higher is better"
    notes = [f"Sorted by `{sort}` ({better}). Each value: the mean over the cases with its "
             f"{ranking['level']:.0%} interval from a bootstrap that resamples (source, target) pairs with all their "
             f"cases ({ranking['draws']} draws, seed {ranking['seed']}). Δ: the mean paired difference against "
             f"{_ref_name(ranking)} over the cases both have, with its interval. Rank (by `{sort}`): 1 + the number "
             "of methods surely better (their paired difference's interval excludes 0); `=` marks a rank that "
             "methods share: they are tied. Only methods with every case scored get values.",
             "reads rig: `yes`, the method reads the rig (bones, bone names, skin weights) of its requests; `no`, "
             "meshes only (`MethodMetadata.reads_rig` False): its transfer requests carried no rig."]
    if ranking.get("reference") is None and ranking.get("reference_asked"):
        notes.append(f"No paired differences: the reference `{ranking['reference_asked']}` is not among these "
                     "results (`bench leaderboard --reference`).")
    for c in ranking["columns"]:
        valued = [r for r in ranking["rows"] if r["cells"][c]["cases"] or r["cells"][c]["unscored"]]
        counts = {f"{r['method']} v{r['version']}": r["cells"][c]["unscored"] for r in valued
                  if r["cells"][c]["unscored"]}
        if counts:
            if len(set(counts.values())) == 1 and len(counts) == len(valued):
                said = f"{next(iter(counts.values()))} cases"
            else:
                said = ", ".join(f"{m}: {n}" for m, n in counts.items())
            notes.append(f"`{c}`: {said} have no value (e.g. a character without role labels); the means are "
                         "over the other cases, never with a zero in their place.")
    return notes


def ranking_markdown(ranking: dict) -> list[str]:
    """The ranking table of one protocol (Markdown lines)."""
    cols, ref = ranking["columns"], ranking.get("reference")
    head = ["rank", "method", "reads rig"]
    for c in cols:
        head += [f"{c} [95% CI]", f"Δ {c} vs {_ref_name(ranking)}"]
    lines = ["| " + " | ".join(head) + " |", "|---:|---|---|" + "---:|" * (2 * len(cols))]
    for r in ranking["rows"]:
        cells = [_rank(r["cells"][ranking["sort"]]), f"{r['method']} v{r['version']}", "yes" if r["reads_rig"] else "no"]
        for c in cols:
            cells += [_interval(r["cells"][c]), _difference(r["cells"][c], r["key"] == ref)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines + [""] + [f"- {n}" for n in ranking_notes(ranking)] + [""]


def markdown_tables(agg: dict, strips: list[dict] | None = None, files_dir: str = FILES_DIR) -> str:
    """The leaderboard as Markdown: per protocol the matrix and the summary; then the methods."""
    lines = []
    metrics = [m for m in agg.get("metrics", []) if any(e.get(m) is not None for es in agg["protocols"].values()
                                                          for e in es)] or agg.get("metrics", [])
    for protocol, matrix in agg.get("matrix", {}).items():
        head = matrix["headline"]
        better = "lower is better" if matrix["lower_is_better"] else "higher is better"
        lines += [f"### {_title(agg, protocol)}", ""]
        if protocol in agg.get("ranking", {}):
            lines += ranking_markdown(agg["ranking"][protocol])
        lines += [f"Mean `{head}` per category ({better}); `—`: no average (failed, missing or unsupported cases).", ""]
        cols = matrix["columns"]
        lines.append("| method | " + " | ".join(cols) + f" | {STATUS_HEADER} |")
        lines.append("|---|" + "---:|" * len(cols) + "---|")
        for row in matrix["rows"]:
            cells = " | ".join(_fmt(row["cells"].get(c)) for c in cols)
            lines.append(f"| {row['method']} v{row['version']} | {cells} | {_status(row)} |")
        lines.append("| _cases_ | " + " | ".join(_fmt(n) for n in _column_cases(matrix)) + " | |")
        lines += ["", "All metrics (means over the protocol's cases):", ""]
        header = ["method"] + [t for _, t in COUNT_COLUMNS] + metrics + ["s/case"]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|---|" + "---:|" * (len(header) - 1))
        for e in agg["protocols"].get(protocol, []):
            vals = [_fmt(e.get(k)) for k, _ in COUNT_COLUMNS] + [_fmt(e.get(m)) for m in metrics]
            lines.append(f"| {e['method']} v{e['version']} | " + " | ".join(vals)
                         + f" | {_fmt(e.get('seconds_per_case'), 'seconds_per_case')} |")
        lines.append("")
        for s in strips or []:
            if s["protocol"] == protocol:
                lines += [f"![{s['title']}]({files_dir}/{Path(s['path']).name})", ""]
    lines += refused_lines(agg)
    methods = agg.get("methods", {})
    if methods:
        lines += ["### Methods", "", "| method | licence | citation | toolkit | dataset fingerprints | from |",
                  "|---|---|---|---|---|---|"]
        for key, m in methods.items():
            lines.append(f"| {key} | {_md_cell(m.get('licence') or '—')} | {_md_cell(_one_line(m.get('citation')) or '—')} "
                         f"| {m.get('toolkit_version') or '—'} | {_short_fingerprints(m.get('fingerprints'))} "
                         f"| {m.get('source')} |")
        lines.append("")
    return "\n".join(lines)


def _column_cases(matrix: dict) -> list:
    """Cases of each matrix column (the most any method has there; ``all``: their sum), None when no row."""
    out = []
    for c in matrix["columns"]:
        if c == ALL:
            out.append(sum(n for n in out if n is not None) if out else None)
            continue
        counts = [r["counts"].get(c, {}).get("cases") for r in matrix["rows"]]
        counts = [n for n in counts if n is not None]
        out.append(max(counts) if counts else None)
    return out


def _heat(values: list, lower_is_better: bool) -> list[str]:
    """CSS background per value: green for the column's best, red for its worst, on a log scale
    for positive values (so one far-off method does not flatten the rest); blank for None."""
    nums = [v for v in values if v is not None]
    if len(nums) < 2 or max(nums) == min(nums):
        return ["" for _ in values]
    use_log = min(nums) > 0
    f = (lambda v: math.log(v)) if use_log else (lambda v: v)
    lo, hi = f(min(nums)), f(max(nums))
    out = []
    for v in values:
        if v is None:
            out.append("")
            continue
        t = (f(v) - lo) / (hi - lo)
        t = t if lower_is_better else 1 - t  # 0 best, 1 worst
        r, g = int(200 + 55 * t), int(235 - 35 * t)
        b = int(200 - 10 * t)
        out.append(f"background:rgb({r},{g},{b})")
    return out


def _img_tag(png: bytes, alt: str) -> str:
    return f"<img alt='{html.escape(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode()}'>"


def ranking_html(ranking: dict) -> str:
    """The ranking table of one protocol (HTML): ``table.ranking``, tied rows ``tr.tied``, the
    rank cell ``td.rank`` (``=2`` when shared), reads-rig cells ``td.rig-yes`` / ``td.rig-no``."""
    e = html.escape
    cols, ref = ranking["columns"], ranking.get("reference")
    parts = ["<table class='ranking'><tr><th>rank</th><th>method</th><th>reads rig</th>"
             + "".join(f"<th>{e(c)} [95% CI]</th><th>Δ {e(c)} vs {e(_ref_name(ranking))}</th>" for c in cols)
             + "</tr>"]
    for r in ranking["rows"]:
        sort_cell = r["cells"][ranking["sort"]]
        rig = "yes" if r["reads_rig"] else "no"
        tds = "".join(f"<td class='ci' title='{r['cells'][c]['cases']} cases, {r['cells'][c]['pairs']} pairs'>"
                      f"{e(_interval(r['cells'][c]))}</td><td class='ci'>{e(_difference(r['cells'][c], r['key'] == ref))}"
                      "</td>" for c in cols)
        parts.append(f"<tr class='{'tied' if sort_cell.get('tied') else 'ranked'}'><td class='rank'>{e(_rank(sort_cell))}"
                     f"</td><td>{e(r['method'])} v{e(r['version'])}</td><td class='rig-{rig}'>{rig}</td>{tds}</tr>")
    parts.append("</table><ul class='notes'>" + "".join(f"<li>{_md_code(n)}</li>" for n in ranking_notes(ranking))
                 + "</ul>")
    return "".join(parts)


def _md_code(text: str) -> str:
    """Escaped HTML of a note, its backquoted parts as ``<code>``."""
    pieces = html.escape(text).split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(pieces))


def html_page(agg: dict, plots: dict[str, bytes] | None = None, strips: list[dict] | None = None,
              note: str | None = None) -> str:
    """The self-contained HTML page (images embedded as base64 PNG)."""
    e = html.escape
    metrics = agg.get("metrics", [])
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>mimicbench leaderboard</title>",
             "<style>body{font-family:sans-serif;margin:2em;max-width:1600px}table{border-collapse:collapse;"
             "margin:.5em 0 1em}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}"
             "td:first-child,th:first-child{text-align:left}td.status{text-align:left;color:#555}"
             "table.methods td,table.methods th{text-align:left;vertical-align:top}"
             "figure{margin:1em 0}figcaption{font-size:90%;color:#444}img{max-width:100%}"
             "pre{white-space:pre-wrap;margin:0;font-size:85%;text-align:left}"
             "table.ranking td:nth-child(2),table.ranking td:nth-child(3){text-align:left;white-space:nowrap}"
             "table.ranking td.rank{text-align:center;font-weight:bold}table.ranking tr.tied td.rank{color:#1f5fa8}"
             "td.rig-no{color:#2b7a3d}td.rig-yes{color:#555}td.ci{white-space:nowrap}ul.notes{font-size:90%;color:#333}"
             "</style></head><body>",
             "<h1>mimicbench leaderboard</h1>"]
    run = agg.get("run", {})
    parts.append(f"<p>Dataset: <code>{e(str(run.get('dataset', '—')))}</code>. PMD x100: mean vertex distance in "
                 "percent of the normalising size of the reference rest mesh; ELS: 1 - mean |edge length ratio - 1| "
                 "(1 is perfect). A method with failed, missing or unsupported cases gets no average (—); the "
                 f"<i>{STATUS_HEADER}</i> column counts them.</p>")
    if note:
        parts.append(f"<p><i>{e(note)}</i></p>")
    if strips:
        parts.append("<p>Pictures (Blender Workbench) of a few sampled cases a protocol: <span style='color:#5485cc'>"
                     "posed source</span>, <span style='color:#5cb36b'>ground truth</span>, <span style='color:#ed9440'>"
                     "each method's prediction</span>, <span style='color:#9e73c7'>the source each method returned"
                     "</span> (cct), <span style='color:#999'>target at rest</span>. Panels on one character share a "
                     "camera, so offsets show; a panel's note says when it had to be re-centred or zoomed out.</p>")
    for protocol, matrix in agg.get("matrix", {}).items():
        head, cols = matrix["headline"], matrix["columns"]
        better = "lower is better" if matrix["lower_is_better"] else "higher is better"
        parts.append(f"<section class='protocol' id='{e(protocol)}'><h2>{e(_title(agg, protocol))}</h2>")
        if protocol in agg.get("ranking", {}):
            parts.append(ranking_html(agg["ranking"][protocol]))
        parts.append(f"<p>Mean <code>{e(head)}</code> per category ({better}).</p>")
        parts.append("<table class='matrix'><tr><th>method</th>" + "".join(f"<th>{e(c)}</th>" for c in cols)
                     + f"<th>{e(STATUS_HEADER)}</th></tr>")
        shades = {c: _heat([r["cells"].get(c) for r in matrix["rows"]], matrix["lower_is_better"]) for c in cols}
        for i, row in enumerate(matrix["rows"]):
            tds = []
            for c in cols:
                n = row["counts"].get(c, {}).get("cases") if c != ALL else row["ok"] + row["failed"]
                tip = f" title='{n} cases'" if n is not None else ""
                tds.append(f"<td style='{shades[c][i]}'{tip}>{e(_fmt(row['cells'].get(c)))}</td>")
            parts.append(f"<tr><td>{e(row['method'])} v{e(row['version'])}</td>" + "".join(tds)
                         + f"<td class='status'>{e(_status(row))}</td></tr>")
        parts.append("<tr class='cases'><td><i>cases</i></td>" + "".join(f"<td>{e(_fmt(n))}</td>"
                                                                       for n in _column_cases(matrix))
                     + "<td></td></tr></table>")
        if plots and protocol in plots:
            parts.append(f"<figure class='plot'>{_img_tag(plots[protocol], f'{protocol} per category')}"
                         "<figcaption>Per category; a log axis when values span more than 10x.</figcaption></figure>")
        present = [m for m in metrics if any(x.get(m) is not None for x in agg["protocols"].get(protocol, []))]
        parts.append("<details><summary>all metrics</summary><table><tr><th>method</th>"
                     + "".join(f"<th>{e(t)}</th>" for _, t in COUNT_COLUMNS)
                     + "".join(f"<th>{e(m)}</th>" for m in present) + "<th>s/case</th><th>first error</th></tr>")
        for x in agg["protocols"].get(protocol, []):
            parts.append(f"<tr><td>{e(x['method'])} v{e(x['version'])}</td>"
                         + "".join(f"<td>{e(_fmt(x.get(k)))}</td>" for k, _ in COUNT_COLUMNS)
                         + "".join(f"<td>{e(_fmt(x.get(m)))}</td>" for m in present)
                         + f"<td>{e(_fmt(x.get('seconds_per_case'), 'seconds_per_case'))}</td>"
                         f"<td class='status'>{e(_one_line(x.get('first_error') or '', 80))}</td></tr>")
        parts.append("</table></details>")
        for s in strips or []:
            if s["protocol"] == protocol:
                parts.append(f"<figure class='strip'>{_img_tag(Path(s['path']).read_bytes(), s['title'])}</figure>")
        parts.append("</section>")
    refused = agg.get("refused") or []
    if refused:
        parts.append(f"<h2>Rows not averaged</h2><p>{len(refused)} result rows failed the checks and were left out; "
                     "their methods get no average.</p><table class='methods'><tr><th>method</th><th>protocol</th>"
                     "<th>case</th><th>reason</th></tr>")
        for r in refused:
            parts.append(f"<tr><td>{e(r['method'])} v{e(r['version'])}</td><td>{e(r['protocol'])}</td>"
                         f"<td>{e(str(r['case_id'] or '—'))}</td><td>{e(r['reason'])}</td></tr>")
        parts.append("</table>")
    methods = agg.get("methods", {})
    if methods:
        parts.append("<h2>Methods</h2><table class='methods'><tr><th>method</th><th>licence</th><th>citation</th>"
                     "<th>description</th><th>toolkit</th><th>dataset fingerprints</th><th>created</th>"
                     "<th>from</th></tr>")
        for key, m in methods.items():
            cite = m.get("citation") or ""
            cite_html = f"<details><summary>{e(_one_line(cite, 60))}</summary><pre>{e(cite)}</pre></details>" \
                if len(cite) > 60 or "\n" in cite else e(cite or "—")
            parts.append(f"<tr><td>{e(key)}</td><td>{e(m.get('licence') or '—')}</td><td>{cite_html}</td>"
                         f"<td>{e(m.get('description') or '—')}</td><td>{e(str(m.get('toolkit_version') or '—'))}</td>"
                         f"<td>{e(_short_fingerprints(m.get('fingerprints')))}</td>"
                         f"<td>{e(str(m.get('created') or '—'))}</td><td>{e(str(m.get('source')))}</td></tr>")
        parts.append("</table>")
        fps = {json.dumps(m.get("fingerprints"), sort_keys=True) for m in methods.values() if m.get("fingerprints")}
        if len(fps) > 1:
            parts.append("<p><b>Warning:</b> the methods' results come from different dataset fingerprints.</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _els_metric(agg: dict, protocol: str) -> str | None:
    for name in ("els", "els_forward"):
        if any(c.get(name) is not None for c in agg["categories"].get(protocol, [])):
            return name
    return None


def _write_text(path: Path, text: str) -> None:
    """Write a leaderboard file atomically (a full disk leaves the old file, never half a new one)."""
    atomic_write_bytes(path, text.encode("utf-8"))


class _CsvFile(io.StringIO):
    """A text buffer for :mod:`csv` that is written atomically to ``path`` on a clean exit."""

    def __init__(self, path: Path):
        super().__init__(newline="")
        self.path = path

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            _write_text(self.path, self.getvalue())
        return super().__exit__(exc_type, exc, tb)


def default_out(results) -> Path:
    """Where ``bench leaderboard RESULTS`` writes by default: ``RESULTS-leaderboard`` beside the
    results folder, never into it (a leaderboard written into it would change the folder that
    ``bench run`` wrote and that the leaderboard reads)."""
    results = Path(results).absolute()
    return results.with_name(results.name + "-leaderboard")


def write_leaderboard(results, out_dir=None, pictures: bool = True, reference: str | None = DEFAULT_REFERENCE
                      ) -> dict[str, Path]:
    """Write the leaderboard files into ``out_dir`` (default: the results folder).

    Args:
        results: results folder (``<method>/<version>/part-*.parquet``, ``run.json``).
        pictures: render strips of sampled cases through Blender; when Blender is missing or
            fails, the page says why and everything else is still written.
        reference: the method (name or ``name/version``) every paired difference is taken
            against; None for none.

    Returns:
        Paths by kind: ``md``, ``csv``, ``matrix_csv``, ``ranking_csv``, ``json``, ``html``,
        ``files`` (folder).
    """
    check_results_provenance(results)  # refuses results of different dataset states
    agg = aggregate(results, reference)
    out = Path(out_dir or results)
    try:
        return _write_files(results, agg, out, pictures)
    except OSError as exc:  # a full disk or a read-only folder: name the folder, keep the reason
        from mimicbench.runtime.errors import os_error_at

        raise os_error_at(exc, out) from exc


def _write_files(results, agg: dict, out: Path, pictures: bool) -> dict[str, Path]:
    from mimicbench.benchmark.plots import protocol_figure_png

    files = out / FILES_DIR
    files.mkdir(parents=True, exist_ok=True)
    plots = {}
    for protocol, matrix in agg["matrix"].items():
        plots[protocol] = protocol_figure_png(protocol, matrix, agg["categories"].get(protocol, []),
                                              _els_metric(agg, protocol))
        atomic_write_bytes(files / f"plot-{protocol}.png", plots[protocol])
    strips, note = [], None
    if pictures:
        from mimicbench.benchmark.leaderboard_strips import build_strips, render_strips
        from mimicbench.datagen.render.render import RenderError

        todo, note = build_strips(results, agg)
        try:
            strips = render_strips(todo, files) if todo else []
        except RenderError as exc:
            note = f"no pictures: {exc}"
    else:
        note = "pictures not rendered (--no-pictures)"
    paths = {ext: out / f"leaderboard.{ext}" for ext in ("md", "csv", "json", "html")}
    paths["matrix_csv"] = out / "leaderboard_matrix.csv"
    paths["ranking_csv"] = out / "leaderboard_ranking.csv"
    paths["files"] = files
    md = markdown_tables(agg, strips)
    for protocol in plots:
        heading = f"### {_title(agg, protocol)}\n"
        md = md.replace(heading, f"{heading}\n![{protocol} per category]({FILES_DIR}/plot-{protocol}.png)\n", 1)
    _write_text(paths["md"], "# mimicbench leaderboard\n\n" + (f"_{note}_\n\n" if note else "") + md)
    _write_text(paths["json"], json.dumps(agg, indent=2, default=str) + "\n")
    metrics = agg["metrics"]
    ranking = agg.get("ranking", {})
    with _CsvFile(paths["csv"]) as f:
        w = csv.writer(f)
        w.writerow(["protocol", "method", "version"] + [k for k, _ in COUNT_COLUMNS] + metrics
                   + ["seconds_per_case", "complete", "first_error", "reads_rig", "rank_by", "rank", "tied"])
        for protocol, entries in agg["protocols"].items():
            rk = ranking.get(protocol, {})
            by = {r["key"]: r for r in rk.get("rows", [])}
            for x in entries:
                r = by.get(f"{x['method']}/{x['version']}")
                cell = r["cells"][rk["sort"]] if r else {}
                w.writerow([protocol, x["method"], x["version"]] + [x.get(k) for k, _ in COUNT_COLUMNS]
                           + [x.get(m) for m in metrics] + [x["seconds_per_case"], x["complete"], x["first_error"]]
                           + [r["reads_rig"] if r else None, rk.get("sort"), cell.get("rank"), cell.get("tied")])
    with _CsvFile(paths["ranking_csv"]) as f:
        w = csv.writer(f)
        fields = ["mean", "lo", "hi", "cases", "pairs", "unscored", "rank", "tied", "diff", "diff_lo", "diff_hi",
                  "diff_se", "diff_cases"]
        w.writerow(["protocol", "column", "method", "version", "reads_rig", "reference"] + fields)
        for protocol, rk in ranking.items():
            for c in rk["columns"]:
                for r in rk["rows"]:
                    w.writerow([protocol, c, r["method"], r["version"], r["reads_rig"], rk["reference"]]
                               + [r["cells"][c].get(k) for k in fields])
    with _CsvFile(paths["matrix_csv"]) as f:
        w = csv.writer(f)
        w.writerow(["protocol", "headline", "method", "version", "category", "value", "cases"])
        for protocol, matrix in agg["matrix"].items():
            for row in matrix["rows"]:
                for c in matrix["columns"]:
                    n = row["counts"].get(c, {}).get("cases") if c != ALL else row["ok"] + row["failed"]
                    w.writerow([protocol, matrix["headline"], row["method"], row["version"], c, row["cells"].get(c), n])
    _write_text(paths["html"], html_page(agg, plots, strips, note))
    return paths
