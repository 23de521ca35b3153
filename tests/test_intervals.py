"""Pair-clustered intervals and standard errors against a naive loop and hand computations; the
leaderboard's ranking (intervals, paired differences, ties, unscored cases) on hand-made results."""
from __future__ import annotations

import math

import numpy as np
import pyarrow.parquet as pq
import pytest

from mimicbench.benchmark.aggregate import aggregate
from mimicbench.benchmark.intervals import (bootstrap_interval, cluster_bootstrap_means, pair_clustered_se, pair_of,
                                 paired_difference, tie_ranks)
from mimicbench.benchmark.leaderboard import write_leaderboard
from mimicbench.benchmark.results import append_results, write_run_info
from mimicbench.schemas.result import ResultRecord


def _naive_interval(values, pairs, draws, seed, level=0.95):
    """A plain loop: clusters by sorted pair ID, one drawn index row per draw, every case of a drawn
    pair added one by one, then the percentile by sorting and interpolating by hand."""
    ids = sorted(set(pairs))
    members = {p: [v for v, q in zip(values, pairs) if q == p] for p in ids}
    rows = np.random.default_rng(seed).integers(0, len(ids), size=(draws, len(ids)))
    means = []
    for row in rows:
        total, count = 0.0, 0
        for g in row:
            for v in members[ids[int(g)]]:
                total += v
                count += 1
        means.append(total / count)
    means.sort()

    def quantile(q):
        pos = q * (len(means) - 1)
        below = math.floor(pos)
        above = min(below + 1, len(means) - 1)
        return means[below] + (pos - below) * (means[above] - means[below])

    return quantile((1 - level) / 2), quantile(1 - (1 - level) / 2)


def test_bootstrap_interval_matches_a_naive_loop():
    rng = np.random.default_rng(3)
    pairs = [f"s{i % 7}->t{i % 3}" for i in range(40)]  # 21 pairs of 1 to 3 cases (unequal sizes)
    values = list(rng.normal(4.0, 2.0, 40) + np.array([hash(p) % 5 for p in pairs]))
    for seed, draws in ((0, 500), (11, 301)):
        assert bootstrap_interval(values, pairs, draws=draws, seed=seed) == \
            pytest.approx(_naive_interval(values, pairs, draws, seed), rel=1e-12, abs=1e-12)
    # the row order does not matter; a pair drawn twice counts twice: with one pair the mean is fixed
    order = rng.permutation(40)
    assert bootstrap_interval([values[i] for i in order], [pairs[i] for i in order]) == \
        pytest.approx(bootstrap_interval(values, pairs), rel=1e-12)
    assert bootstrap_interval([1.0, 3.0], ["p", "p"]) == (2.0, 2.0)


def test_stacked_columns_share_draws_and_give_paired_differences():
    rng = np.random.default_rng(5)
    pairs = [f"p{i % 6}" for i in range(30)]
    a, b = rng.normal(2, 1, 30), rng.normal(2.5, 1, 30)
    both = cluster_bootstrap_means(np.stack([a, b], axis=1), pairs)
    assert both[:, 0] == pytest.approx(cluster_bootstrap_means(a, pairs), rel=1e-12)
    assert both[:, 0] - both[:, 1] == pytest.approx(cluster_bootstrap_means(a - b, pairs), rel=1e-9, abs=1e-12)
    ids = [f"cct/zoo/s{i % 6}->zoo/t/m#{i}" for i in range(30)]
    d = paired_difference(dict(zip(ids, a)), {**dict(zip(ids, b)), ids[0]: None})  # case 0: only a has it
    assert d["cases"] == 29 and d["pairs"] == 6 and d["diff"] == pytest.approx(float(np.mean(a[1:] - b[1:])))
    assert (d["lo"], d["hi"]) == pytest.approx(_naive_interval(list(a[1:] - b[1:]), [pair_of(k) for k in ids[1:]],
                                                                2000, 0), rel=1e-9)


def test_pair_clustered_se_by_hand():
    # mean 4; residual sums per pair a: -3-2 = -5, b: -1, c: 0+6 = 6; 3 pairs: 3/2 * (25+1+36), over N = 5
    assert pair_clustered_se([1.0, 2.0, 3.0, 4.0, 10.0], ["a", "a", "b", "c", "c"]) == \
        pytest.approx(math.sqrt(1.5 * 62.0) / 5.0)
    # one case a pair: the ordinary standard error, sqrt(14/3) / 2
    assert pair_clustered_se([1.0, 2.0, 3.0, 6.0], list("wxyz")) == pytest.approx(math.sqrt(14.0 / 3.0) / 2.0)
    # a paired difference: a - b = (2, 3, 1, 4) in pairs x, y, x, y; residual sums -2 and 2; 2/1 * 8, over 4
    a, b = np.array([3.0, 5.0, 4.0, 8.0]), np.array([1.0, 2.0, 3.0, 4.0])
    assert pair_clustered_se(a - b, ["x", "y", "x", "y"]) == pytest.approx(1.0)
    assert math.isnan(pair_clustered_se([1.0, 2.0], ["x", "x"]))  # one pair: no standard error
    with pytest.raises(ValueError, match="one pair ID per value"):
        pair_clustered_se([1.0, 2.0], ["x"])
    with pytest.raises(ValueError, match="finite"):
        bootstrap_interval([1.0, float("nan")], ["x", "y"])


def test_pair_of_reads_ids_with_slashes():
    assert pair_of("cct/zoo/humanoid-0001->zoo/bird-0003/walk#12") == "zoo/humanoid-0001->zoo/bird-0003"
    assert pair_of("h2h/assets/Fox->assets/Fox_b/Survey#0") == "assets/Fox->assets/Fox_b"
    assert pair_of("c1") == "c1"


def test_ties_are_not_chained():
    # A surely better than C; B tied with both: A and B share rank 1, C has 2 (not 1 through B)
    assert tie_ranks(["A", "B", "C"], {("A", "C"): True}) == {"A": 1, "B": 1, "C": 2}
    assert tie_ranks(["A", "B", "C"], {("A", "B"): True, ("A", "C"): True, ("B", "C"): True}) == \
        {"A": 1, "B": 2, "C": 3}


def _row(case_id, method, pmd, semantic, out_of_range=0.1):
    return ResultRecord(case_id, "cct", method, "1", "ok", None, 0.1, pmd, pmd, 0.9, 0.95, "humanoid", "bird",
                        pmd_height=pmd, pmd_extent=pmd, pmd_aligned=pmd, semantic_deg=semantic,
                        out_of_range=out_of_range)


@pytest.fixture
def ranked_results(tmp_path):
    """cct: 6 pairs x 3 cases; the reference, a close method (tied), a mirrored one (cycle as good,
    semantic far worse) and one with a failed case; pair 0's cases have no semantic score."""
    rng = np.random.default_rng(2)
    res = tmp_path / "res"
    ids = [f"cct/zoo/h{p}->zoo/b{p}/walk#{f}" for p in range(6) for f in range(3)]
    pmd = rng.normal(5.0, 1.0, len(ids))
    sem = rng.normal(10.0, 1.0, len(ids))
    lacks = {k for k in ids if "h0->" in k}
    # close: +1 on pairs 1, 3, 5 and -1 on pairs 2, 4 (its paired interval spans 0); mirror: 30 degrees off
    offsets = {"nearest_joint": lambda i: 0.0, "close": lambda i: 1.0 if (i // 3) % 2 else -1.0,
               "mirror": lambda i: 30.0 + rng.normal(0.0, 0.5)}
    for name, dp in (("nearest_joint", 0.0), ("close", 0.01), ("mirror", -0.01)):
        append_results(res / name / "1", [_row(k, name, p + dp, None if k in lacks else s + offsets[name](i))
                                          for i, (k, p, s) in enumerate(zip(ids, pmd, sem))])
    broken = [_row(k, "broken", p, s) for k, p, s in zip(ids, pmd, sem)]
    broken[3] = ResultRecord(ids[3], "cct", "broken", "1", "failed", "boom", 0.1, None, None, None, None,
                             "humanoid", "bird")
    append_results(res / "broken" / "1", broken)
    write_run_info(res, {"dataset": "nowhere", "protocols": {"cct": len(ids)}, "case_ids": {"cct": ids}})
    return res, ids, lacks


def test_ranking_has_intervals_differences_ties_and_unscored_counts(ranked_results):
    res, ids, lacks = ranked_results
    rk = aggregate(res)["ranking"]["cct"]
    assert rk["columns"] == ["semantic_deg", "pmd_extent", "out_of_range", "els_forward"]  # semantic first on cct
    assert rk["sort"] == "semantic_deg" and rk["reference"] == "nearest_joint/1"
    rows = {r["method"]: r for r in rk["rows"]}
    assert [r["method"] for r in rk["rows"]][-1] == "broken"  # no values: last
    assert all(c["mean"] is None and c["rank"] is None for c in rows["broken"]["cells"].values())
    sem = {m: rows[m]["cells"]["semantic_deg"] for m in ("nearest_joint", "close", "mirror")}
    assert all(s["unscored"] == len(lacks) and s["cases"] == len(ids) - len(lacks) and s["pairs"] == 5
               for s in sem.values())
    # the mirrored method: surely worse; the close one: tied with the reference
    assert (sem["nearest_joint"]["rank"], sem["close"]["rank"], sem["mirror"]["rank"]) == (1, 1, 3)
    assert sem["nearest_joint"]["tied"] and sem["close"]["tied"] and not sem["mirror"]["tied"]
    assert sem["mirror"]["diff_lo"] > 25 and sem["close"]["diff_lo"] < 0 < sem["close"]["diff_hi"]
    assert sem["nearest_joint"]["diff"] is None  # the reference itself
    # a difference over the cases both have, against a hand-made loop over the rows
    agg = aggregate(res)
    m = next(e for e in agg["protocols"]["cct"] if e["method"] == "mirror")
    assert sem["mirror"]["mean"] == pytest.approx(m["semantic_deg"])
    assert sem["mirror"]["lo"] < sem["mirror"]["mean"] < sem["mirror"]["hi"]
    # the cycle PMD: every method within 0.01 of the reference by construction (constant offsets)
    pmd = {r["method"]: r["cells"]["pmd_extent"] for r in rk["rows"]}
    assert pmd["mirror"]["diff"] == pytest.approx(-0.01) and pmd["mirror"]["diff_lo"] == pytest.approx(-0.01)


def test_ranking_files_and_an_absent_reference(ranked_results):
    res, ids, lacks = ranked_results
    paths = write_leaderboard(res, res.parent / "board", pictures=False, reference="no_such_method")
    md = paths["md"].read_text()
    assert "| =1 | nearest_joint v1 | yes |" in md and "| 3 | mirror v1 | yes |" in md
    assert f"`semantic_deg`: {len(lacks)} cases have no value" in md
    assert "the reference `no_such_method` is not among these results" in md
    lines = paths["ranking_csv"].read_text().splitlines()
    assert lines[0].startswith("protocol,column,method,version,reads_rig,reference,mean,lo,hi")
    assert len(lines) == 1 + 4 * 4  # 4 columns x 4 methods
    head = paths["csv"].read_text().splitlines()[0].split(",")
    assert head[-4:] == ["reads_rig", "rank_by", "rank", "tied"]


def test_an_older_results_folder_without_the_new_columns(ranked_results):
    res, ids, _ = ranked_results
    for part in res.glob("*/1/part-*.parquet"):  # as written before the forward scores existed
        table = pq.read_table(part)
        pq.write_table(table.drop([c for c in ("semantic_deg", "role_classes_scored", "out_of_range")
                                   if c in table.column_names]), part)
    rk = aggregate(res)["ranking"]["cct"]
    assert rk["columns"] == ["pmd_extent", "els_forward"] and rk["sort"] == "pmd_extent"
    assert all(r["cells"]["pmd_extent"]["unscored"] == 0 for r in rk["rows"])
    assert write_leaderboard(res, res.parent / "old", pictures=False)["html"].exists()
