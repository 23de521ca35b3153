"""Leaderboard: the method x category matrix against hand-computed means, statuses, provenance,
the sample store, and (with Blender) the page's pictures."""
from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest

from mimicbench.benchmark.aggregate import aggregate, category_column, headline_metric, method_info
from mimicbench.benchmark.leaderboard import write_leaderboard
from mimicbench.benchmark.plots import uses_log_axis
from mimicbench.benchmark.results import append_results, write_run_info
from mimicbench.benchmark.samples import SampleSink, read_sample, sample_case_ids, sample_path
from mimicbench.schemas.case import CaseRecord
from mimicbench.schemas.result import ResultRecord


def row(case_id, method, src, tgt, pmd, status="ok", protocol="cct", els=0.9):
    ok = status == "ok"
    value = pmd if ok else None  # real rows: pmd is pmd_height on h2h, pmd_extent on cct
    return ResultRecord(case_id, protocol, method, "1", status, None if ok else f"{status} on purpose", 0.5,
                        value, value, els if ok else None, els if ok else None, src, tgt,
                        pmd_height=value, pmd_extent=value, pmd_aligned=value)


@pytest.fixture
def hand_results(tmp_path):
    """Two methods on 5 cct cases: humanoid->bird, bird->humanoid, humanoid->reptile (x2), humanoid->fish."""
    res = tmp_path / "res"
    cases = [("c1", "humanoid", "bird"), ("c2", "bird", "humanoid"), ("c3", "humanoid", "reptile"),
             ("c4", "apparel", "reptile"), ("c5", "humanoid", "fish")]
    a = [2.0, 4.0, 100.0, 300.0, 7.0]
    b = [1.0, 3.0, 10.0, None, 5.0]  # c4 failed
    append_results(res / "good" / "1", [row(c, "good", s, t, v) for (c, s, t), v in zip(cases, a)])
    append_results(res / "flaky" / "1", [row(c, "flaky", s, t, v, "ok" if v is not None else "failed")
                                         for (c, s, t), v in zip(cases, b)])
    write_run_info(res, {"dataset": "nowhere", "protocols": {"cct": 5}})
    return res


def test_matrix_cells_are_hand_computed_means(hand_results):
    agg = aggregate(hand_results)
    m = agg["matrix"]["cct"]
    assert m["columns"] == ["bird", "fish", "reptile", "all"]
    good = next(r for r in m["rows"] if r["method"] == "good")
    assert good["cells"] == {"bird": pytest.approx(3.0), "fish": pytest.approx(7.0), "reptile": pytest.approx(200.0),
                             "all": pytest.approx(413.0 / 5)}
    flaky = next(r for r in m["rows"] if r["method"] == "flaky")
    # the failed reptile case: no reptile average, no overall average; the other columns stand
    assert flaky["cells"] == {"bird": pytest.approx(2.0), "fish": pytest.approx(5.0), "reptile": None, "all": None}
    assert (flaky["missing"], flaky["failed"], flaky["not_supported"]) == (0, 1, 0)
    assert [r["method"] for r in m["rows"]] == ["good", "flaky"]  # ranked; no average goes last
    md = write_leaderboard(hand_results, hand_results.parent / "board", pictures=False)["md"].read_text()
    assert "| _cases_ | 2 | 1 | 2 | 5 | |" in md  # each category's case count under the matrix


def test_missing_and_not_supported_cases(hand_results):
    write_run_info(hand_results, {"protocols": {"cct": 6}})  # one case never run
    append_results(hand_results / "picky" / "1", [row("c1", "picky", "humanoid", "bird", None, "not_supported")])
    agg = aggregate(hand_results)
    rows = {r["method"]: r for r in agg["matrix"]["cct"]["rows"]}
    assert rows["good"]["missing"] == 1 and all(v is None for v in rows["good"]["cells"].values())
    assert (rows["picky"]["missing"], rows["picky"]["not_supported"]) == (5, 1)
    md = (write_leaderboard(hand_results, pictures=False)["md"]).read_text()
    assert "missing / failed / not supported" in md and "| 5 / 0 / 1 |" in md and "| 1 / 0 / 0 |" in md


def test_category_column_rule():
    assert category_column("humanoid", "bird") == category_column("bird", "humanoid") == "bird"
    assert category_column("apparel", "reptile") == "reptile"
    assert category_column("humanoid", "apparel") == "apparel"  # h2h: the target
    assert category_column("fish", "bird") == "fish->bird"


def test_headline_metric_prefers_protocol_normalisation():
    assert headline_metric("h2h", ["pmd", "pmd_height", "pmd_extent"]) == "pmd_height"
    assert headline_metric("cct", ["pmd", "pmd_height", "pmd_extent"]) == "pmd_extent"
    assert headline_metric("cct", ["pmd", "els"]) == "pmd"


def test_method_info_from_meta_json_then_registry(hand_results):
    assert method_info(hand_results, "good", "1")["source"] == "unknown"
    reg = method_info(hand_results, "identity", "1")
    assert reg["source"] == "registry" and reg["licence"]
    meta = {"method": {"name": "good", "version": "1", "licence": "Apache-2.0", "citation": "Doe et al. 2025",
                       "description": "a good method"}, "toolkit_version": "0.1.0", "dataset": "nowhere",
            "fingerprints": {"characters": "cd" * 32, "pairs": None, "cases": {"cct": "ab" * 32}},
            "created": "2026-11-30T08:00:00Z"}
    (hand_results / "good" / "1" / "meta.json").write_text(json.dumps(meta))
    info = method_info(hand_results, "good", "1")
    assert (info["licence"], info["citation"], info["toolkit_version"], info["source"]) == \
        ("Apache-2.0", "Doe et al. 2025", "0.1.0", "meta.json")
    paths = write_leaderboard(hand_results, pictures=False)
    page = paths["html"].read_text()
    assert "Apache-2.0" in page and "Doe et al. 2025" in page
    assert "cases.cct abababababab, characters cdcdcdcdcdcd" in page and "pairs" not in page.split("Methods")[-1]
    assert re.search(r"<table class='matrix'>", page) and page.count("data:image/png;base64,") == 1  # the plot
    lines = paths["matrix_csv"].read_text().splitlines()
    assert lines[0].startswith("protocol,headline,method") and len(lines) == 1 + 2 * 4


def test_log_axis_when_one_category_is_far_off():
    assert uses_log_axis([2.0, 3.0, 300.0]) and not uses_log_axis([2.0, 3.0, 9.0]) and not uses_log_axis([0.0, 50.0])


def _case(cid, src_cat, tgt_cat, protocol="cct", src="a", tgt="b"):
    return CaseRecord(cid, protocol, src, tgt, "m", 1, np.zeros((1, 7), np.float32), None, src_cat, tgt_cat)


def test_sample_ids_are_deterministic_and_span_category_pairs():
    cases = [_case(f"cct/x{i}", "humanoid", ["bird", "fish", "reptile"][i % 3]) for i in range(60)]
    ids = sample_case_ids(cases, 3)
    assert ids == sample_case_ids(list(reversed(cases)), 3)  # order of the list does not matter
    assert len({c.target_category for c in cases if c.case_id in ids}) == 3
    assert sample_case_ids(cases[:2], 3) == sample_case_ids(cases[:2], 5) and len(sample_case_ids(cases[:2], 3)) == 2
    # one category pair: distinct character pairs come before a second pose of the same pair
    same = [_case(f"h2h/{s}->{t}/m#{f}", "humanoid", "humanoid", "h2h", s, t) for s in "ab" for t in "abc" if s != t
            for f in range(10)]
    assert len({tuple(i.split("/")[1:2]) for i in sample_case_ids(same, 3)}) == 3


def test_sample_sink_keeps_both_legs(tmp_path):
    cases = [_case("cct/zoo/a->zoo/b/walk#3", "humanoid", "bird"), _case("cct/other", "humanoid", "bird")]
    sink = SampleSink(tmp_path, {"cct": cases}, k=1)
    kept = next(c for c in cases if c.case_id in sink.sampled["cct"])
    fwd = [(np.full((4, 3), i, np.float32), None, 0.1) for i in range(2)]
    sink.keep(cases, fwd)
    sink.keep(cases, [(np.ones((5, 3), np.float32), None, 0.1), (None, "boom", 0.1)], leg="returned")
    files = list((tmp_path / "samples" / "cct").glob("*.npz"))
    assert files == [sample_path(tmp_path, "cct", kept.case_id)] and "/" not in files[0].name.replace("-", "")
    got = read_sample(tmp_path, "cct", kept.case_id)
    assert set(got) == {"forward", "returned"} and got["forward"].shape == (4, 3) and got["returned"].shape == (5, 3)
    with pytest.raises(ValueError, match="leg"):
        sink.keep(cases, fwd, leg="sideways")


def _embedded_images(page: str) -> list[np.ndarray]:
    from PIL import Image

    return [np.asarray(Image.open(io.BytesIO(base64.b64decode(b))).convert("RGB")).astype(float)
            for b in re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page)]


@pytest.fixture(scope="module")
def pictured_board(small_zoo, tmp_path_factory):
    from mimicbench.benchmark.evaluator import run_benchmark
    from tests.bench_fixtures import make_bench_dataset

    root = tmp_path_factory.mktemp("board")
    data = make_bench_dataset(small_zoo, root / "data", h2h_poses=2, cct_pairs=3, cct_poses=1)
    run_benchmark(data, ["identity", "name_copy"], ["h2h", "cct"], root / "res", progress=False)
    return write_leaderboard(root / "res")


@pytest.mark.slow
@pytest.mark.blender
def test_page_shows_matrix_plots_and_rendered_strips(pictured_board):
    page = pictured_board["html"].read_text()
    assert page.count("<table class='matrix'>") == 2 and page.count("<figure class='plot'>") == 2
    assert page.count("<figure class='strip'>") >= 2 and "no pictures" not in page
    images = _embedded_images(page)
    assert len(images) == page.count("<figure")
    for img in images:  # not blank: varied pixels, and neither all background nor all ink
        ink = (img < 235).any(axis=2).mean()
        assert img.std() > 15 and 0.01 < ink < 0.9
    strips = sorted(pictured_board["files"].glob("h2h-*.png")) + sorted(pictured_board["files"].glob("cct-*.png"))
    assert strips and all(f.name in pictured_board["md"].read_text() for f in strips)
    from PIL import Image

    h2h = np.asarray(Image.open(strips[0]).convert("RGB")).astype(int)
    r, g, b = h2h[..., 0], h2h[..., 1], h2h[..., 2]
    # the role colours are on the page: blue source, green ground truth, orange predictions
    assert ((b - r > 40) & (b > g)).sum() > 500 and ((g - r > 25) & (g - b > 25)).sum() > 500
    assert ((r - b > 60) & (r > g)).sum() > 1000


def _chromium() -> str:
    """Debian's chromium: `.ci/run` installs it and sets MIMICBENCH_REQUIRE_CHROMIUM=1, so CI never skips."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        if os.environ.get("MIMICBENCH_REQUIRE_CHROMIUM") == "1":
            pytest.fail("MIMICBENCH_REQUIRE_CHROMIUM=1 but no chromium on PATH (apt-get install chromium)")
        pytest.skip("chromium is not installed (apt-get install chromium); the page's images are checked above")
    return exe


def _offline(tmp_path) -> list[str]:
    """A closed network: nothing the browser would fetch on its own, a fresh profile for each run."""
    return ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run", "--no-default-browser-check",
            f"--user-data-dir={tmp_path / 'profile'}"]


class _RankingRows(HTMLParser):
    """The rows of every ``table.ranking`` in a DOM the browser dumped: [(tr class, [(td class, text)])]."""

    def __init__(self):
        super().__init__()
        self.tables, self.open, self.row, self.cell = [], [], None, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self.open.append(a.get("class"))
            if a.get("class") == "ranking":
                self.tables.append([])
        elif tag == "tr" and self.open and self.open[-1] == "ranking":
            self.row = (a.get("class"), [])
        elif tag == "td" and self.row is not None:
            self.cell = [a.get("class"), ""]

    def handle_data(self, data):
        if self.cell is not None:
            self.cell[1] += data

    def handle_endtag(self, tag):
        if tag == "table" and self.open:
            self.open.pop()
        elif tag == "td" and self.cell is not None:
            self.row[1].append(tuple(self.cell))
            self.cell = None
        elif tag == "tr" and self.row is not None:
            if self.row[1]:
                self.tables[-1].append(self.row)
            self.row = None


def _browser_ranking(exe, page, tmp_path) -> tuple[list, str]:
    """The ranking tables as the browser built them (its DOM after loading the page), and the DOM."""
    dom = subprocess.run([exe, *_offline(tmp_path), "--dump-dom", page.as_uri()], check=True, capture_output=True,
                         text=True, timeout=180).stdout
    parser = _RankingRows()
    parser.feed(dom)
    return parser.tables, dom


@pytest.mark.slow
@pytest.mark.blender
def test_page_in_a_headless_browser(pictured_board, tmp_path):
    """Needs Debian's chromium: `.ci/run` installs it and sets MIMICBENCH_REQUIRE_CHROMIUM=1, so CI never skips."""
    exe = _chromium()
    shot = tmp_path / "page.png"
    subprocess.run([exe, *_offline(tmp_path), "--hide-scrollbars", "--window-size=1400,4000", f"--screenshot={shot}",
                    pictured_board["html"].as_uri()], check=True, capture_output=True, timeout=180)
    tables, dom = _browser_ranking(exe, pictured_board["html"], tmp_path)
    assert len(tables) == 2  # h2h and cct, each opening with its ranking
    for rows in tables:
        by_method = {cells[1][1].split(" v")[0]: cells for _, cells in rows}
        # identity reads meshes only, name_copy the rig: marked so, and explained under the table
        assert by_method["identity"][2] == ("rig-no", "no") and by_method["name_copy"][2] == ("rig-yes", "yes")
        for cells in by_method.values():  # every mean with its interval: "m [lo, hi]"
            assert re.fullmatch(r"[-0-9.]+ \[[-0-9.]+, [-0-9.]+\]", cells[3][1]), cells[3]
    assert dom.count("reads rig: ") == 2 and "1 + the number of methods surely better" in dom
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    assert ((r - b > 60) & (r > g)).sum() > 1000  # orange predictions drawn by the browser
    assert ((b - r > 40) & (b > g)).sum() > 500  # blue posed sources
    assert ((np.abs(r - g) < 8) & (np.abs(g - b) < 8) & (r > 180) & (r < 240)).sum() > 200  # table header grey


@pytest.mark.slow
def test_ties_and_intervals_in_a_headless_browser(tmp_path):
    """A hand-made cct board with a tie by construction, looked at in chromium (no pictures needed)."""
    exe = _chromium()
    res = tmp_path / "res"
    ids = [f"cct/zoo/h{p}->zoo/b{p}/walk#{f}" for p in range(5) for f in range(2)]
    base = np.linspace(2.0, 6.0, len(ids))
    # "twin" is +1 on pairs 0, 2, 4 and -1 on pairs 1, 3: its paired interval against the reference spans 0
    methods = {"nearest_joint": base, "twin": base + np.where([(i // 2) % 2 == 0 for i in range(len(ids))], 1.0, -1.0),
               "far": base + 40.0}
    for name, vals in methods.items():
        append_results(res / name / "1", [row(k, name, "humanoid", "bird", float(v)) for k, v in zip(ids, vals)])
    write_run_info(res, {"dataset": "nowhere", "protocols": {"cct": len(ids)}, "case_ids": {"cct": ids}})
    page = write_leaderboard(res, tmp_path / "board", pictures=False)["html"]
    (rows,), dom = _browser_ranking(exe, page, tmp_path)
    ranks = {cells[1][1]: (kind, cells[0][1]) for kind, cells in rows}
    assert ranks == {"nearest_joint v1": ("tied", "=1"), "twin v1": ("tied", "=1"), "far v1": ("ranked", "3")}
    diff = {cells[1][1]: cells[4][1] for _, cells in rows}  # the paired difference against nearest_joint
    assert diff["nearest_joint v1"] == "reference" and diff["far v1"] == "+40.000 [+40.000, +40.000]"
    assert "`=` marks" not in dom and "<code>=</code> marks a rank that methods share" in dom


def test_run_dataset_found_from_another_folder(tmp_path, monkeypatch):
    from mimicbench.benchmark.leaderboard_strips import find_dataset

    (tmp_path / "out" / "data").mkdir(parents=True)
    (tmp_path / "out" / "data" / "manifest.json").write_text("{}")
    results = tmp_path / "out" / "results"
    results.mkdir()
    monkeypatch.chdir(results)  # the run recorded "out/data", relative to tmp_path
    assert find_dataset(results, {"dataset": "out/data"}, {}) == tmp_path / "out" / "data"
    assert find_dataset(results, {"dataset": "elsewhere"}, {"m/1": {"dataset": {"not": "a path"}}}) is None
