"""The validity table (benchmark/validity.py) on a results folder written by hand: the paired
difference, its pair-clustered z and the detection flag against values computed in the test."""
from __future__ import annotations

import numpy as np
import pytest

from mimicbench.benchmark.results import append_results, method_dir
from mimicbench.benchmark.validity import markdown_validity, validity_table
from mimicbench.schemas.result import ResultRecord


def rows(method, values, semantic):
    out = []
    for i, (v, s) in enumerate(zip(values, semantic)):
        pair = f"zoo/a-{i // 2}->zoo/b-{i // 2}"  # two cases a pair
        out.append(ResultRecord(f"cct/{pair}/walk#{i}", "cct", method, "1", "ok", None, 0.1, v, None, 0.9, 0.9,
                                "humanoid", "quadruped", semantic_deg=s))
    return out


def test_paired_difference_and_z_by_hand(tmp_path):
    base_pmd = [1.0, 1.2, 0.8, 1.1, 0.9, 1.0]
    base_sem = [5.0, 6.0, 4.0, 5.0, 6.0, 5.0]
    probe_sem = [9.0, 11.0, 8.0, 9.5, 10.0, 9.0]
    append_results(method_dir(tmp_path, "probe_role_transfer", "1"), rows("probe_role_transfer", base_pmd, base_sem))
    append_results(method_dir(tmp_path, "probe_mirror", "1"), rows("probe_mirror", base_pmd, probe_sem))
    table = validity_table(tmp_path)
    sem = next(r for r in table if r["protocol"] == "cct" and r["probe"] == "probe_mirror" and r["column"] == "semantic_deg")
    d = np.array(probe_sem) - np.array(base_sem)
    per_pair = d.reshape(3, 2)
    resid = (per_pair - d.mean()).sum(axis=1)
    se = np.sqrt(3 / 2 * (resid ** 2).sum()) / 6
    assert sem["diff"] == pytest.approx(d.mean())
    assert sem["se"] == pytest.approx(se)
    assert sem["z"] == pytest.approx(d.mean() / se)
    assert sem["detects"] and sem["cases"] == 6 and sem["pairs"] == 3
    pmd = next(r for r in table if r["protocol"] == "cct" and r["probe"] == "probe_mirror" and r["column"] == "pmd")
    assert pmd["diff"] == 0 and not pmd["detects"]  # the cycle cannot see it: identical values
    text = markdown_validity(table)
    assert "left/right mirror" in text and "✓" in text and "✗" in text


def test_higher_is_better_columns_are_signed(tmp_path):
    a = rows("nearest_joint", [1.0] * 4, [5.0] * 4)
    b = rows("nearest_joint_mirrored", [1.0] * 4, [5.0] * 4)
    for r, e in zip(b, (0.5, 0.6, 0.55, 0.5)):
        r.els_forward = e
    append_results(method_dir(tmp_path, "nearest_joint", "1"), a)
    append_results(method_dir(tmp_path, "nearest_joint_mirrored", "1"), b)
    row = next(r for r in validity_table(tmp_path) if r["protocol"] == "cct" and r["probe"] == "nearest_joint_mirrored"
               and r["column"] == "els_forward")
    assert row["diff"] < 0 and row["z"] > 2 and row["detects"]
