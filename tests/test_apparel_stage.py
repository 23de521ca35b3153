"""The apparel stage over a dataset: outputs, determinism, resume, failures, CLI (toy characters)."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from mimicbench.datagen.apparel.params import params_from_json
from mimicbench.datagen.apparel.selection import selection_problem
from mimicbench.datagen.apparel.stage import simulate_dataset
from mimicbench.cli import main
from mimicbench.schemas.shards import read_records, write_records
from mimicbench.schemas.validate import validate_dataset
from tests.apparel_toys import make_character, make_motion, quick_turn


@pytest.fixture
def toy_dataset(tmp_path) -> Path:
    """Two pendulum characters (one without apparel bones) with a turn and a still clip each."""
    root = tmp_path / "toy"
    a = make_character("toy/a")
    b = dataclasses.replace(make_character("toy/b"), apparel_bone_mask=np.zeros(5, bool),
                            apparel_vertex_mask=np.zeros(len(a.vertices), bool))
    write_records(root, "characters", [a, b], split="train")
    motions = [make_motion(c, angles, name) for c in (a, b)
               for name, angles in (("turn", quick_turn(24, 4)), ("still", np.zeros(12)))]
    write_records(root, "motions", motions, split="train")
    return root


def _files(root: Path) -> dict:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_stage_writes_simulated_clips_beside_kinematic_ones(toy_dataset, tmp_path):
    out = tmp_path / "sim"
    s = simulate_dataset(toy_dataset, out, relax=6, progress=False)
    assert s["simulated"] == 2 and s["failed"] == 0 and s["characters"] == 1
    assert validate_dataset(out) == []
    motions = {m.motion_id: m for m in read_records(out, "motions")}
    assert sorted(motions) == ["toy/a/still", "toy/a/still@sim", "toy/a/turn", "toy/a/turn@sim",
                               "toy/b/still", "toy/b/turn"]
    kin, sim = motions["toy/a/turn"], motions["toy/a/turn@sim"]
    assert sim.name == "turn@sim" and sim.fps == kin.fps and sim.transforms.shape == kin.transforms.shape
    np.testing.assert_array_equal(sim.transforms[:, 0], kin.transforms[:, 0])  # body bone untouched
    assert np.abs(sim.transforms[:, 1:, 4:] - kin.transforms[:, 1:, 4:]).max() > 0.05  # apparel lags
    src = {m.motion_id: m for m in read_records(toy_dataset, "motions")}
    np.testing.assert_array_equal(kin.transforms, src["toy/a/turn"].transforms)  # kinematic clip kept
    chars = {c.character_id: c for c in read_records(out, "characters")}
    clips = chars["toy/a"].meta["apparel"]["clips"]
    assert set(clips) == {"turn", "still"}
    assert clips["turn"]["secondary_motion_max_pct"] > clips["still"]["secondary_motion_max_pct"]
    assert clips["still"]["new_inside_pct"] == pytest.approx(0.0, abs=1e-9) and clips["turn"]["max_edge_stretch"] < 1e-3  # one bone a piece
    status = {(r.asset, r.status) for r in read_records(out, "status", "apparel")}
    assert status == {("toy/a/turn", "ok"), ("toy/a/still", "ok"), ("toy/b", "skipped")}


def test_stage_is_deterministic_and_resumes(toy_dataset, tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    simulate_dataset(toy_dataset, one, relax=6, progress=False)
    simulate_dataset(toy_dataset, two, relax=6, progress=False)
    assert _files(one) == _files(two)  # byte-identical, every shard and the manifest
    again = simulate_dataset(toy_dataset, one, relax=6, progress=False)
    assert again["reused"] == 2 and again["simulated"] == 0
    assert _files(one) == _files(two)
    changed = simulate_dataset(toy_dataset, one, relax=7, progress=False)  # other parameters: recomputed
    assert changed["reused"] == 0 and changed["simulated"] == 2


def test_exploding_parameters_become_status_rows(toy_dataset, tmp_path):
    out = tmp_path / "boom"
    s = simulate_dataset(toy_dataset, out, relax=6, params=params_from_json({"simulation": {"gravity": 10000.0}}),
                         progress=False)
    assert s["failed"] == 2 and s["simulated"] == 0
    rows = [r for r in read_records(out, "status", "apparel") if r.status == "failed"]
    assert {r.asset for r in rows} == {"toy/a/turn", "toy/a/still"}
    assert all("SimulationExploded" in r.reason and "m/s" in r.reason for r in rows)
    assert all("after 5 re-settles (max_resettles 5)" in r.reason for r in rows)  # the default limit
    names = sorted(m.motion_id for m in read_records(out, "motions"))
    assert names == ["toy/a/still", "toy/a/turn", "toy/b/still", "toy/b/turn"]  # kinematic clips kept
    assert validate_dataset(out) == []


def test_a_clip_whose_chain_escapes_is_resettled_and_kept(toy_dataset, tmp_path):
    # a 2 m/s speed bound: the turn swings the chain past it a few times, each time re-settled (the
    # frames in the clip's quality); the still clip never reaches it and gives the bytes of a run
    # at the default bound
    plain, low = tmp_path / "plain", tmp_path / "low"
    simulate_dataset(toy_dataset, plain, relax=6, progress=False)
    params = params_from_json({"simulation": {"max_speed": 2.0, "max_resettles": 50}})
    s = simulate_dataset(toy_dataset, low, relax=6, params=params, progress=False)
    assert s["simulated"] == 2 and s["failed"] == 0 and s["resettled"] == 1
    clips = read_records(low, "characters")[0].meta["apparel"]["clips"]
    turn, still = clips["turn"], clips["still"]
    assert 0 < turn["resettles"] <= 50 and turn["resettles"] == len(turn["resettled_frames"])
    assert turn["resettled_frames"] == sorted(set(turn["resettled_frames"]))
    assert all(-6 <= f < 24 for f in turn["resettled_frames"])
    assert still["resettles"] == 0 and still["resettled_frames"] == []
    motions = [{m.motion_id: m for m in read_records(root, "motions")} for root in (plain, low)]
    assert motions[0]["toy/a/still@sim"].transforms.tobytes() == motions[1]["toy/a/still@sim"].transforms.tobytes()
    assert motions[0]["toy/a/turn@sim"].transforms.tobytes() != motions[1]["toy/a/turn@sim"].transforms.tobytes()
    assert validate_dataset(low) == []


def test_apparel_bones_by_glob_choose_bones_and_vertices(toy_dataset, tmp_path):
    out = tmp_path / "glob"
    s = simulate_dataset(toy_dataset, out, relax=0, apparel_bones=["skirt_3", "SKIRT_4"], progress=False)
    assert s["characters"] == 2 and s["simulated"] == 4  # toy/b has the bones too, by name
    c = {c.character_id: c for c in read_records(out, "characters")}["toy/b"]
    np.testing.assert_array_equal(c.apparel_bone_mask, [0, 0, 0, 1, 1])
    owner = c.weight_indices[:, 0]  # one-hot toy weights
    np.testing.assert_array_equal(c.apparel_vertex_mask, np.isin(owner, [3, 4]))
    sim = {m.motion_id: m for m in read_records(out, "motions")}["toy/b/turn@sim"]
    kin = {m.motion_id: m for m in read_records(out, "motions")}["toy/b/turn"]
    np.testing.assert_array_equal(sim.transforms[:, :3], kin.transforms[:, :3])  # skirt_1, skirt_2 now body


@pytest.mark.parametrize("patterns,needle", [(["*"], "every bone of the skeleton (5)"),
                                             (["torso"], "apparel bone 'torso' hangs from no body bone")])
def test_a_selection_that_cannot_hang_from_the_body_fails_its_clips_and_keeps_them(toy_dataset, tmp_path,
                                                                                   patterns, needle):
    out = tmp_path / "bad"
    s = simulate_dataset(toy_dataset, out, relax=0, apparel_bones=patterns, progress=False)
    assert s["simulated"] == 0 and s["failed"] == 4  # both characters' two clips
    rows = [r for r in read_records(out, "status") if r.status == "failed"]
    assert len(rows) == 4 and all(needle in r.reason and "--apparel-bones" in r.reason for r in rows)
    assert sorted(m.name for m in read_records(out, "motions")) == ["still", "still", "turn", "turn"]
    assert validate_dataset(out) == []


def test_selection_problem_by_hand():
    names = ["root", "spine", "hair_1", "hair_2", "tail"]
    parents = np.array([-1, 0, 1, 2, 0])
    some = np.array([True, False])
    assert selection_problem(names, parents, np.array([0, 0, 1, 1, 0], bool), some) is None
    assert "'root' hangs from no body bone" in selection_problem(names, parents, np.array([1, 0, 0, 0, 0], bool), some)
    # under an apparel root: the first apparel bone found without a body bone above it is named
    assert "hangs from no body bone" in selection_problem(names, parents, np.array([1, 0, 0, 0, 1], bool), some)
    assert "every bone" in selection_problem(names, parents, np.ones(5, bool), some)
    assert "no vertex" in selection_problem(names, parents, np.array([0, 0, 0, 0, 1], bool), np.zeros(2, bool))


def test_cli_runs_and_rejects_bad_options(toy_dataset, tmp_path, capsys):
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"kinds": {"skirt": {"stiffness": 0.05}}}))
    assert main(["datagen", "apparel", str(toy_dataset), str(tmp_path / "cli"), "--relax-frames", "4",
                 "--params", str(params), "--quiet"]) == 0
    assert "2 clips simulated" in capsys.readouterr().out
    for bad in (["--fps", "0"], ["--relax-frames", "-1"], ["--jobs", "0"], ["--gravity", "-1"]):
        with pytest.raises(SystemExit) as exc:
            main(["datagen", "apparel", str(toy_dataset), str(tmp_path / "x")] + bad)
        assert exc.value.code == 2
    params.write_text(json.dumps({"kinds": {"skirt": {"stiffness": 5}}}))
    assert main(["datagen", "apparel", str(toy_dataset), str(tmp_path / "y"), "--params", str(params)]) == 2
    assert "expected a number >= 0 and <= 1" in capsys.readouterr().err
    assert main(["datagen", "apparel", str(toy_dataset), str(toy_dataset)]) == 2


def test_cli_exit_status_follows_the_share_of_failed_clips(toy_dataset, tmp_path, capsys):
    # gravity 10000 explodes both of toy/a's clips (toy/b has no apparel): 2 of 2 failed, a share of 1.0
    params = tmp_path / "boom.json"
    params.write_text(json.dumps({"simulation": {"gravity": 10000.0}}))
    args = ["datagen", "apparel", str(toy_dataset), str(tmp_path / "a"), "--relax-frames", "4", "--params",
            str(params), "--quiet"]
    assert main(args) == 1  # default --max-failed 0.05
    assert "2 failed clips (100.0 % of the clips" in capsys.readouterr().out
    assert main(args[:3] + [str(tmp_path / "b")] + args[4:] + ["--max-failed", "1"]) == 0  # all may fail
    assert len([r for r in read_records(tmp_path / "b", "status", "apparel") if r.status == "failed"]) == 2
    with pytest.raises(SystemExit) as exc:
        main(args + ["--max-failed", "1.5"])
    assert exc.value.code == 2
