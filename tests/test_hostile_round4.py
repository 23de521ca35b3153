"""Hostile inputs, round 4 (issue 51): names from files used as paths, concurrent writers, checkpoints
written in two pieces, cyclic skeletons, flat characters, FBX files that import strangely, pipeline
files that break late, and a harness whose own worker start-up fails. One test (or more) per item."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from mimicbench.cli import main

HEAD = "[pipeline]\nname = 't'\n"


def _pipeline(tmp_path, text: str) -> Path:
    path = tmp_path / "p.toml"
    path.write_text(text)
    return path


def _one_line(capsys, *needles) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith("mimicbench: error: "), err
    first = err.splitlines()[0]
    for n in needles:
        assert n in first, first
    return first


# --- 1. the pipeline's name is a plain name, never a path ---------------------------------------------

@pytest.mark.parametrize("name", ["../../../victim/manifest", "/tmp/abs_name", "a/b", "..", "", "a\\\\b"])
def test_a_pipeline_name_that_is_a_path_is_refused_and_writes_nothing(tmp_path, capsys, name):
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "manifest.json").write_text('{"keep": true}')
    work = tmp_path / "a" / "b" / "w"
    path = _pipeline(tmp_path, f"[pipeline]\nname = \"{name}\"\n[[steps]]\nrun = 'zoo'\nout = 'zoo'\ncharacters = 2\n"
                               "no_contact_sheet = true\nquiet = true\n")
    assert main(["pipeline", str(path), "--workdir", str(work), "--quiet"]) == 2
    _one_line(capsys, "[pipeline] name", "expected a plain name")
    assert json.loads((victim / "manifest.json").read_text()) == {"keep": True}
    assert not work.exists() and not Path("/tmp/abs_name.json").exists()


# --- 11. two steps writing one folder are refused when the file is read ---------------------------------

@pytest.mark.parametrize("steps, needle", [
    ("[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nname = 'again'\nrun = 'zoo'\nout = 'z'\n", "step 1 (zoo)"),
    ("[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nrun = 'resample'\nin = 'z'\nout = 'z'\n", "step 1 (zoo)"),
    ("[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nrun = 'bench'\ndataset = 'z'\nmethods = 'identity'\nout = 'z'\n",
     "step 1 (zoo)"),
    ("[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nrun = 'bench'\ndataset = 'z'\nmethods = 'identity'\n"
     "out = 'z/characters'\n", "step 1 (zoo)"),
    ("[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nrun = 'bench'\ndataset = 'z'\nmethods = 'identity'\nout = 'r'\n"
     "[[steps]]\nrun = 'leaderboard'\nresults = 'z'\nout = 'r/board'\n", "step 2 (bench)"),
])
def test_two_steps_writing_one_folder_are_refused_before_anything_runs(tmp_path, capsys, steps, needle):
    work = tmp_path / "w"
    assert main(["pipeline", str(_pipeline(tmp_path, HEAD + steps)), "--workdir", str(work), "--quiet"]) == 2
    _one_line(capsys, "writes too", needle, "own output folder")
    assert not work.exists()


def test_steps_writing_other_tables_of_one_folder_are_fine(tmp_path):
    from mimicbench.pipeline import load_pipeline

    text = (HEAD + "[[steps]]\nrun = 'zoo'\nout = 'z'\n[[steps]]\nrun = 'correspond'\ndataset = 'z'\n"
            "[[steps]]\nrun = 'cases'\ndataset = 'z'\n[[steps]]\nrun = 'bench'\ndataset = 'z'\nmethods = 'identity'\n"
            "out = 'z/results'\n")
    assert [s.kind for s in load_pipeline(_pipeline(tmp_path, text), tmp_path / "w").steps] == \
        ["zoo", "correspond", "cases", "bench"]


# --- 12. the whole file is checked before the first step runs ------------------------------------------

@pytest.mark.parametrize("methods, needle", [("5", "methods = 5"), ("[1, 2]", "methods = [1, 2]"),
                                             ("'identity,no_such_method'", "unknown method 'no_such_method'")])
def test_a_wrong_bench_methods_value_fails_before_the_first_step(tmp_path, capsys, methods, needle):
    work = tmp_path / "w"
    text = (HEAD + "[[steps]]\nrun = 'zoo'\nout = 'z'\ncharacters = 2\nno_contact_sheet = true\nquiet = true\n"
            f"[[steps]]\nrun = 'cases'\ndataset = 'z'\n[[steps]]\nrun = 'bench'\ndataset = 'z'\nmethods = {methods}\n"
            "out = 'r'\n")
    path = _pipeline(tmp_path, text)
    assert main(["pipeline", str(path), "--workdir", str(work), "--quiet"]) == 2
    _one_line(capsys, "step 3 (bench)", needle)
    assert not (work / "z").exists()  # the zoo step never ran
    assert main(["pipeline", str(path), "--workdir", str(work), "--dry-run"]) == 2
    _one_line(capsys, "step 3 (bench)", needle)


# --- a small humanoid zoo, and copies of it with one character broken -----------------------------------

@pytest.fixture(scope="module")
def humanoids(tmp_path_factory) -> Path:
    """Four zoo humanoids, one 12-frame clip each (read only: copy before writing)."""
    from mimicbench.datagen.zoo.dataset import build_zoo

    root = tmp_path_factory.mktemp("humanoids") / "zoo"
    build_zoo(root, 4, seed=0, categories=["humanoid"], clips_per_character=1, frames_per_clip=12, progress=False)
    return root


def _broken_copy(src: Path, dst: Path, change) -> str:
    """A copy of dataset ``src`` at ``dst`` whose last character is passed through ``change(record)``;
    returns that character's ID."""
    import shutil

    from mimicbench.schemas.shards import read_records, write_records

    shutil.copytree(src, dst)
    chars = read_records(dst, "characters")
    victim = chars[-1]
    change(victim)
    write_records(dst, "characters", [c for c in chars if c.split == victim.split], victim.split)
    return victim.character_id


def _cyclic(rec) -> None:
    """parents[k] = k + 2 for one joint below the root: a loop the format's order forbids."""
    parents = rec.parents.copy()
    parents[3] = 5
    rec.parents = parents


def _flat(rec) -> None:
    """Every vertex and joint at Y = 0: a character with no height."""
    rec.vertices = rec.vertices.copy()
    rec.vertices[:, 1] = 0.0
    rec.keypoints = rec.keypoints.copy()
    rec.keypoints[:, 1] = 0.0


# --- 5. a cyclic skeleton: validate fails it, retarget and resample fail the item -------------------------

def test_a_cyclic_skeleton_fails_validate_retarget_and_resample(humanoids, tmp_path, capsys):
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.datagen.retarget.stage import retarget_datasets
    from mimicbench.schemas.shards import read_records
    from mimicbench.schemas.validate import parents_problem, validate_dataset

    assert parents_problem([-1, 0, 1, 1]) is None
    assert "parents[2] = 2 is not below 2" in parents_problem([-1, 0, 2, 1])
    assert "parents[1] = 3" in parents_problem([-1, 3, 1, 0])
    data = tmp_path / "cyc"
    cid = _broken_copy(humanoids, data, _cyclic)
    problems = validate_dataset(data, values=True)
    assert any(f"character {cid}: parents[3] = 5 is not below 3" in p for p in problems), problems
    assert main(["validate", str(data)]) == 1
    out = retarget_datasets(data, humanoids, tmp_path / "rt", progress=False)
    rows = {s.asset: s for s in out["statuses"]}
    bad = [s for a, s in rows.items() if a.startswith(cid + "/")]  # its clips onto the (healthy) others
    assert bad and all(s.status == "failed" and "parents[3] = 5 is not below 3" in s.reason for s in bad), bad
    assert not any(m.source.startswith(f"retarget:{cid}/") for m in read_records(tmp_path / "rt", "motions"))
    out = retarget_datasets(humanoids, data, tmp_path / "rt2", progress=False)
    onto = [s for s in out["statuses"] if s.asset.endswith("-> " + cid)]
    assert onto and all(s.status == "failed" and "target " + cid in s.reason for s in onto), onto
    assert cid not in {c.character_id for c in read_records(tmp_path / "rt2", "characters")}
    summary = resample_dataset(data, tmp_path / "rs", faces=2000, progress=False)
    (row,) = [s for s in summary["statuses"] if s.asset == cid]
    assert row.status == "failed" and "parents[3] = 5" in row.reason
    assert cid not in {c.character_id for c in read_records(tmp_path / "rs", "characters")}


# --- 8. resample of a flat character: a failed row, never an inf --------------------------------------

def test_resampling_a_flat_character_fails_its_row_and_stores_no_inf(humanoids, tmp_path):
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.schemas.shards import read_records

    data = tmp_path / "flat"
    cid = _broken_copy(humanoids, data, _flat)
    summary = resample_dataset(data, tmp_path / "rs", faces=2000, progress=False)
    (row,) = [s for s in summary["statuses"] if s.asset == cid]
    assert row.status == "failed" and "no height" in row.reason
    stored = read_records(tmp_path / "rs", "characters")
    assert cid not in {c.character_id for c in stored} and len(stored) == 3
    assert all(float(v) < 1e6 for c in stored for v in (c.meta["resample"]["hausdorff_pct"],
                                                         c.meta["resample"]["transfer_error_pct"]))
    assert main(["validate", str(tmp_path / "rs")]) == 0


# --- 10. retarget whose globs match nothing: an error, no dataset --------------------------------------

@pytest.mark.parametrize("option, needle", [("--sources", "--sources 'nobody*' matches none of the 4 characters"),
                                            ("--targets", "--targets 'nobody*' matches none of the 4 characters")])
def test_retarget_globs_matching_nothing_is_an_error_and_writes_nothing(humanoids, tmp_path, capsys, option, needle):
    out = tmp_path / "rt"
    assert main(["datagen", "retarget", str(humanoids), str(humanoids), str(out), option, "nobody*", "--quiet"]) == 2
    _one_line(capsys, needle)
    assert not out.exists()


# --- 14. a flat character: validate, bench cases and bench run name it up front ---------------------------

def test_a_flat_character_is_named_by_validate_cases_and_run_before_any_row(humanoids, tmp_path, capsys):
    from mimicbench.schemas.validate import validate_dataset

    data = tmp_path / "flat"
    cid = _broken_copy(humanoids, data, _flat)
    assert any(f"character {cid}: its rest mesh has no height" in p for p in validate_dataset(data, values=True))
    assert main(["bench", "cases", str(data), "--all-pairs", "--h2h-poses", "1", "--cct-poses", "1"]) == 2
    _one_line(capsys, "1 character(s) whose rest mesh has no height", cid)
    from mimicbench.benchmark.cases import build_cases, write_cases

    # cases made as `bench cases` made them before it checked heights (so a dataset of that time)
    write_cases(data, build_cases(data, "all", None, 1, 2, 1, 0, all_pairs=True), {"stage": "bench cases"})
    res = tmp_path / "res"
    assert main(["bench", "run", str(data), "--methods", "identity,nearest_joint", "--out", str(res), "--quiet"]) == 2
    _one_line(capsys, "whose rest mesh has no height", "used by", cid)
    assert not res.exists()



# --- 2. one writer at a time per dataset or results folder ---------------------------------------------

def _start(*argv: str):
    """``mimicbench ARGV`` as a separate process (stderr piped, to read its waiting line)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    return subprocess.Popen([sys.executable, "-m", "mimicbench", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _waiting_line(proc) -> str:
    """The first stderr line of ``proc`` that says it waits for the folder's writer ('' if it ended first)."""
    for line in proc.stderr:
        if line.startswith("waiting: "):
            return line
    return ""


def _two_writers_behind_ours(folder: Path, first: list[str], second: list[str]):
    """Hold ``folder``'s writer's lock here, start two commands writing it, check that both wait naming
    this process, let them go, and return their (exit status, stdout, stderr)."""
    import os

    from mimicbench.schemas.folder_lock import hold

    lock = hold(folder)
    procs = [_start(*first), _start(*second)]
    try:
        lines = [_waiting_line(p) for p in procs]
        for line in lines:
            assert f"is being written by pid {os.getpid()} (" in line and str(folder.resolve()) in line, lines
    finally:
        lock.release()
    done = []
    for p in procs:
        out, err = p.communicate(timeout=600)
        done.append((p.returncode, out, err))
    return done


@pytest.mark.parametrize("splits", [("train", "train"), ("train", "test")])
def test_two_ingests_into_one_dataset_wait_for_each_other_and_lose_nothing(tmp_path, splits):
    from mimicbench.schemas.shards import read_records
    from mimicbench.schemas.validate import validate_dataset
    from tests.mmd_fixtures import pmx_bytes

    for group in ("a", "b"):
        (tmp_path / group).mkdir()
        for i in range(4):
            (tmp_path / group / f"{group}{i}.pmx").write_bytes(pmx_bytes(encoding=i % 2))
    ds = tmp_path / "ds"
    done = _two_writers_behind_ours(ds, ["datagen", "ingest", str(tmp_path / "a"), "--out", str(ds), "--split",
                                         splits[0], "--quiet"],
                                    ["datagen", "ingest", str(tmp_path / "b"), "--out", str(ds), "--split", splits[1],
                                     "--quiet"])
    assert [rc for rc, *_ in done] == [0, 0], done
    chars = read_records(ds, "characters")
    assert sorted(c.character_id for c in chars) == [f"assets/{g}{i}" for g in "ab" for i in range(4)]
    assert {c.character_id[-2]: c.split for c in chars} == {"a": splits[0], "b": splits[1]}
    rows = {s.asset.rsplit("/", 1)[-1] for s in read_records(ds, "status") if s.status == "ok"}
    assert {f"{g}{i}.pmx" for g in "ab" for i in range(4)} <= rows
    assert validate_dataset(ds, values=True) == []
    assert not (tmp_path / ".ds.lock").exists()


def test_two_bench_runs_into_one_results_folder_wait_and_store_each_case_once(humanoids, tmp_path):
    import shutil

    import pyarrow.parquet as pq

    data = tmp_path / "data"
    shutil.copytree(humanoids, data)
    assert main(["bench", "cases", str(data), "--all-pairs", "--h2h-poses", "1", "--cct-poses", "1",
                 "--protocols", "h2h"]) == 0
    res = tmp_path / "res"
    run = ["bench", "run", str(data), "--methods", "identity", "--protocols", "h2h", "--out", str(res), "--quiet",
           "--in-process"]
    done = _two_writers_behind_ours(res, run, run)
    assert [rc for rc, *_ in done] == [0, 0], done
    cases = pq.read_table(data / "cases", columns=["case_id"]).column("case_id").to_pylist()
    parts = sorted(res.rglob("part-*.parquet"))
    stored = [pq.read_table(p, columns=["case_id", "status"]).to_pylist() for p in parts]
    ids = [r["case_id"] for rows in stored for r in rows]
    assert sorted(ids) == sorted(cases) and all(r["status"] == "ok" for rows in stored for r in rows)
    assert sum("0 cases computed" in out for _, out, _ in done) == 1  # the second found every case done


# --- 3, 9, 13. training: one atomic resume point, a stranger's refused, frozen stages verified ---------------

@pytest.fixture(scope="module")
def toy_data(tmp_path_factory):
    from tests import training_toys

    return training_toys.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy")


def _toy_config():
    import copy

    from tests import training_toys

    return copy.deepcopy(training_toys.CONFIG)


def _weights(path):
    from mimicbench.training import checkpoint

    return checkpoint.load_checkpoint(path)[0]


def test_a_kill_between_the_weights_and_the_state_leaves_the_old_pair_and_resume_goes_on(toy_data, tmp_path,
                                                                                        monkeypatch):
    import torch

    from mimicbench.training import checkpoint
    from mimicbench.training.loop import train_stage

    full = _weights(train_stage("toy", "fit", toy_data, tmp_path / "full", _toy_config(), epochs=3, seed=2,
                                progress=False))
    run = tmp_path / "run"
    real_save_state = checkpoint.save_state
    calls = []

    def dies_at_epoch_2(path, state):  # the process ends after epoch 2's weights reached the disk
        calls.append(state["epoch"])
        if state["epoch"] == 2:
            raise KeyboardInterrupt
        return real_save_state(path, state)

    monkeypatch.setattr(checkpoint, "save_state", dies_at_epoch_2)
    with pytest.raises(KeyboardInterrupt):
        train_stage("toy", "fit", toy_data, run, _toy_config(), epochs=3, seed=2, progress=False)
    monkeypatch.setattr(checkpoint, "save_state", real_save_state)
    assert calls == [1, 2]
    resumed = _weights(train_stage("toy", "fit", toy_data, run, _toy_config(), epochs=3, seed=2, progress=False))
    assert all(torch.equal(full[k], resumed[k]) for k in full)  # resumed from epoch 1, not started over
    import csv

    with open(run / "fit" / "loss.csv") as f:
        assert sorted({int(r["epoch"]) for r in csv.DictReader(f)}) == [0, 1, 2]


def test_resume_refuses_another_seed_or_dataset_in_one_line(toy_data, tmp_path, capsys):
    import shutil

    from mimicbench.training import checkpoint
    from mimicbench.training.loop import train_stage
    from mimicbench.schemas.errors import UserError
    from tests import training_toys

    mine, theirs = tmp_path / "mine", tmp_path / "theirs"
    train_stage("toy", "fit", toy_data, theirs, _toy_config(), epochs=1, seed=7, progress=False)
    train_stage("toy", "fit", toy_data, mine, _toy_config(), epochs=1, seed=0, progress=False)
    # a stranger's resume point (same config, seed 7) copied over this run's
    shutil.rmtree(mine / "fit")
    shutil.copytree(theirs / "fit", mine / "fit")
    with pytest.raises(UserError, match=r"with another seed \(seed 7, this run's 0\)"):
        train_stage("toy", "fit", toy_data, mine, _toy_config(), epochs=2, seed=0, progress=False)
    # only the weights swapped in, the state left: the weights' header and sha256 give it away
    other = tmp_path / "other"
    train_stage("toy", "fit", toy_data, other, _toy_config(), epochs=1, seed=0, progress=False)
    w_theirs, _ = checkpoint.find_resume(theirs / "fit")
    w_other, _ = checkpoint.find_resume(other / "fit")
    w_other.write_bytes(w_theirs.read_bytes())
    checkpoint.digest_path(w_other).write_bytes(checkpoint.digest_path(w_theirs).read_bytes())
    with pytest.raises(UserError):
        train_stage("toy", "fit", toy_data, other, _toy_config(), epochs=2, seed=0, progress=False)
    # the same run folder continued on another dataset
    elsewhere = training_toys.write_toy_dataset(tmp_path / "toy_b", seed=1)
    run = tmp_path / "run"
    train_stage("toy", "fit", toy_data, run, _toy_config(), epochs=1, seed=0, progress=False)
    capsys.readouterr()
    assert main(["train", "toy", str(elsewhere), "--out", str(run), "--stage", "fit", "--epochs", "2",
                 "--no-progress"]) == 2
    _one_line(capsys, "on another dataset ('toy'; tables toy.npz differ", "--no-resume")


def test_a_needed_stage_without_its_digest_or_of_another_network_is_refused(toy_data, tmp_path):
    from mimicbench.training import checkpoint
    from mimicbench.training.loop import train_model, train_stage
    from mimicbench.schemas.errors import UserError

    run = tmp_path / "run"
    train_model("toy", ["fit"], toy_data, run, _toy_config(), epochs=1, progress=False)
    model = run / "fit" / "model.safetensors"
    checkpoint.digest_path(model).unlink()
    with pytest.raises(UserError, match=r"model\.safetensors: no model\.safetensors\.sha256 beside it"):
        train_stage("toy", "head", toy_data, run, _toy_config(), epochs=1, progress=False)
    # a checkpoint of another stage put in its place (digest and all) is named, not loaded
    other = tmp_path / "other"
    train_model("toy", "all", toy_data, other, _toy_config(), epochs=1, progress=False)
    head = other / "head" / "model.safetensors"
    model.write_bytes(head.read_bytes())
    checkpoint.digest_path(model).write_bytes(checkpoint.digest_path(head).read_bytes())
    with pytest.raises(UserError, match="a checkpoint of model 'toy', stage 'head'; expected one of model 'toy', "
                                        "stage 'fit'"):
        train_stage("toy", "head", toy_data, run, _toy_config(), epochs=1, progress=False)


def test_a_checkpoint_of_another_network_is_one_line_naming_both(toy_data, tmp_path):
    import torch

    from mimicbench.training import checkpoint
    from mimicbench.training.loop import train_stage
    from tests import training_toys

    path = train_stage("toy", "fit", toy_data, tmp_path, _toy_config(), epochs=1, progress=False)
    wide = _toy_config()
    wide["fit"]["width"] = 2 * wide["fit"]["width"]
    with pytest.raises(checkpoint.CheckpointMismatch) as err:
        checkpoint.load_module(path, lambda cfg: training_toys._build_fit(wide, None))
    text = str(err.value)
    assert "\n" not in text and "weights do not fit" in text and "of another shape" in text
    with pytest.raises(checkpoint.CheckpointMismatch, match="whose config does not build this network"):
        checkpoint.load_module(path, lambda cfg: torch.nn.Linear(cfg["no such key"], 1))
    with pytest.raises(ValueError):  # still a ValueError for callers that catch those
        checkpoint.load_module(path, lambda cfg: torch.nn.Linear(3, 1))


@pytest.mark.parametrize("kind, needle", [("pickle", "a pickle that loading without running code refuses"),
                                          ("garbage", "not a readable checkpoint"),
                                          ("list", "holds a list, not a state dict of tensors"),
                                          ("other", "weights of another network (2 missing (e.g. 'weight')")])
def test_a_pickle_garbage_or_foreign_clip_checkpoint_is_one_line(tmp_path, kind, needle):
    import os
    import pickle

    import torch

    from mimicbench.datagen.correspond.encoders import _clip_state
    from mimicbench.runtime.errors import UserError

    path = tmp_path / f"{kind}.pt"
    if kind == "pickle":
        path.write_bytes(pickle.dumps({"run": os.system}))
    elif kind == "garbage":
        path.write_bytes(bytes(range(256)) * 3)
    elif kind == "list":
        torch.save([torch.zeros(2)], path)
    else:
        torch.save({"other.weight": torch.zeros(2, 2)}, path)
    net = torch.nn.Linear(2, 2)
    with pytest.raises(UserError) as err:
        _clip_state(str(path), "ViT-B-32", net)
    assert needle in str(err.value) and "\n" not in str(err.value)
    assert "expected a state dict of open_clip model 'ViT-B-32'" in str(err.value)
    torch.save(net.state_dict(), tmp_path / "fits.pt")
    assert set(_clip_state(str(tmp_path / "fits.pt"), "ViT-B-32", torch.nn.Linear(2, 2))) == {"weight", "bias"}


def test_correspond_with_a_pickle_as_clip_pretrained_is_one_line(humanoids, tmp_path, capsys):
    import os
    import pickle
    import shutil

    data = tmp_path / "data"
    shutil.copytree(humanoids, data)
    evil = tmp_path / "evil.pt"
    evil.write_bytes(pickle.dumps({"run": os.system}))
    assert main(["datagen", "correspond", str(data), "--encoder", "clip", "--clip-pretrained", str(evil),
                 "--quiet"]) == 2
    _one_line(capsys, f"--clip-pretrained {evil}: not a readable checkpoint", "expected a state dict")


# --- 15. a script without the main guard: one start-up error, nothing stored as the method's failure --------

PLUGIN = '''
import sys

import numpy as np

from mimicbench.benchmark.evaluator import run_benchmark
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.benchmark.registry import register


class MyMethod(PoseTransferMethod):
    metadata = MethodMetadata(name="my_method", version="0.1", licence="MIT")

    def transfer(self, requests):
        return [np.asarray(r.target.vertices, np.float32) for r in requests]


register("my_method", MyMethod)
{guard}
run_benchmark(sys.argv[1], ["my_method", "name_copy"], ("h2h",), sys.argv[2], progress=False)
'''


def test_an_unguarded_plugin_script_is_one_start_up_error_and_a_rerun_computes_the_cases(humanoids, tmp_path):
    import os
    import shutil
    import subprocess
    import sys

    import pyarrow.parquet as pq

    data = tmp_path / "data"
    shutil.copytree(humanoids, data)
    assert main(["bench", "cases", str(data), "--all-pairs", "--h2h-poses", "1", "--protocols", "h2h"]) == 0
    cases = pq.read_table(data / "cases", columns=["case_id"]).num_rows
    res = tmp_path / "res"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    script = tmp_path / "my_method.py"
    script.write_text(PLUGIN.replace("{guard}", ""))
    run = subprocess.run([sys.executable, str(script), str(data), str(res)], capture_output=True, text=True, env=env,
                         timeout=600)
    assert run.returncode != 0
    assert run.stderr.count("WorkerStartError: the harness could not start a worker process for method "
                            "'name_copy'") == 1, run.stderr
    assert f"the script {script} starts mimicbench work at its top level" in run.stderr
    assert 'if __name__ == "__main__":' in run.stderr and "No case was run or stored" in run.stderr
    assert "RuntimeError" not in run.stderr and "AssertionError" not in run.stderr
    stored = {p.parts[-3] for p in res.rglob("part-*.parquet")}
    assert stored == {"my_method"}  # nothing of name_copy's, failed or otherwise
    script.write_text(PLUGIN.replace("{guard}", 'if __name__ == "__main__":').replace(
        "\nrun_benchmark(", "\n    run_benchmark("))
    run = subprocess.run([sys.executable, str(script), str(data), str(res)], capture_output=True, text=True, env=env,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    rows = [r for p in res.rglob("part-*.parquet") if p.parts[-3] == "name_copy"
            for r in pq.read_table(p, columns=["status"]).to_pylist()]
    assert len(rows) == cases and all(r["status"] == "ok" for r in rows)


# --- 4, 6. FBX: all-zero skin weights fail the row; a mirrored armature's faces point outward ----------------

BOX_RIG = """
import bpy, sys
scale, weight, out = float(sys.argv[-3]), float(sys.argv[-2]), sys.argv[-1]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("RigData"))
scene.collection.objects.link(rig)
bpy.context.view_layer.objects.active = rig
bpy.ops.object.mode_set(mode="EDIT")
root = rig.data.edit_bones.new("Root")
root.head, root.tail = (0, 0, 0), (0, 0, 0.5)
top = rig.data.edit_bones.new("Top")
top.head, top.tail, top.parent, top.use_connect = (0, 0, 0.5), (0, 0, 1.0), root, True
bpy.ops.object.mode_set(mode="OBJECT")
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, 0.2, 0.5))
box = bpy.context.active_object
box.name, box.parent = "Box", rig
for name in ("Root", "Top"):
    box.vertex_groups.new(name=name).add([v.index for v in box.data.vertices if (v.co.z > 0) == (name == "Top")],
                                         weight, "REPLACE")
box.modifiers.new("Armature", "ARMATURE").object = rig
rig.scale = (scale, 1, 1)
rig.animation_data_create()
rig.animation_data.action = bpy.data.actions.new("Bend")
bone = rig.pose.bones["Top"]
bone.rotation_mode = "XYZ"
for frame, angle in ((0, 0.0), (10, 0.5)):
    bone.rotation_euler = (angle, 0, 0)
    bone.keyframe_insert("rotation_euler", frame=frame)
bpy.ops.export_scene.fbx(filepath=out, bake_anim=True, add_leaf_bones=False)
"""


def _box_fbx(path: Path, x_scale: float, weight: float) -> Path:
    """A unit cube (centre (0.3, 0.2, 0.5) in Blender's Z-up frame) skinned to a two-bone armature whose
    object has scale (x_scale, 1, 1), every vertex weighted ``weight`` to one bone, saved by Blender."""
    from tests.fbx_fixtures import _blender

    _blender(BOX_RIG, x_scale, weight, path)
    return path


def _signed_volume(v, f) -> float:
    """Volume enclosed by a closed triangle mesh: sum of det[a, b, c] / 6 (positive when faces point outward)."""
    import numpy as np

    v = np.asarray(v, np.float64)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


@pytest.mark.slow
def test_an_fbx_armature_with_negative_scale_stores_outward_faces(tmp_path):
    import numpy as np

    from mimicbench.datagen.ingest.runner import ingest_assets
    from mimicbench.schemas.shards import read_records
    from tests.fbx_reference import ufbx_vertices

    assert _signed_volume([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                          np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])) == pytest.approx(1 / 6)
    for name, scale in (("mirrored", -1.0), ("plain", 1.0)):
        path = _box_fbx(tmp_path / f"{name}.fbx", scale, 1.0)
        out = tmp_path / f"ds_{name}"
        ingest_assets([path], out, progress=False)
        (char,) = read_records(out, "characters")
        assert len(char.vertices) == 8 and len(char.faces) == 12
        assert _signed_volume(char.vertices, char.faces) == pytest.approx(1.0, abs=1e-4), name  # outward: +1 m^3
        ref = np.concatenate(ufbx_vertices(path, ["Box"], {})["rest"])  # a second reader's world vertices
        centre = np.array([0.3 * scale, 0.5, -0.2])  # Blender (x, y, z) -> dataset (x, z, -y)
        assert np.allclose(ref.mean(axis=0), centre, atol=1e-5)
        dist = np.linalg.norm(char.vertices[:, None, :] - ref[None, :, :], axis=-1)
        assert dist.min(axis=1).max() < 1e-5


@pytest.mark.slow
def test_an_fbx_whose_skin_weights_are_all_zero_is_a_failed_row_not_an_empty_character(tmp_path):
    from mimicbench.datagen.ingest.runner import ingest_assets
    from mimicbench.schemas.shards import read_records

    zero = _box_fbx(tmp_path / "zero.fbx", 1.0, 0.0)
    good = _box_fbx(tmp_path / "good.fbx", 1.0, 1.0)
    out = tmp_path / "ds"
    summary = ingest_assets([zero, good], out, progress=False)
    rows = {s.asset.rsplit("/", 1)[-1]: s for s in read_records(out, "status")}
    assert rows["zero.fbx"].status == "failed"
    assert "has a skin weight above 0 on a bone" in rows["zero.fbx"].reason and "8 vertices" in rows["zero.fbx"].reason
    assert rows["good.fbx"].status == "ok" and summary["failed"] == 1
    chars = read_records(out, "characters")
    assert [c.character_id for c in chars] == ["assets/good"] and all(len(c.vertices) == 8 for c in chars)


# --- 7. apparel: every stored clip finite and within the documented bounds -----------------------------

def test_clip_bounds_name_the_bound_a_clip_breaks():
    import numpy as np

    from mimicbench.datagen.apparel.clip_bounds import MAX_EDGE_STRETCH, MAX_SECONDARY_MOTION_PCT, ClipOutOfBounds, check_clip_bounds

    t = np.zeros((3, 2, 7))
    t[..., 0] = 1.0
    fine = {"max_edge_stretch": 0.15, "secondary_motion_max_pct": 4.1, "chains": 3, "resettled_frames": []}
    check_clip_bounds(t, fine)
    check_clip_bounds(t, {**fine, "max_edge_stretch": MAX_EDGE_STRETCH, "secondary_motion_max_pct": 50.0})
    for change, words in (({"max_edge_stretch": 1.9}, "max_edge_stretch 1.9 is over the bound 1 (an apparel edge 2.9x"),
                          ({"secondary_motion_max_pct": 113.0}, "secondary_motion_max_pct 113 is over the bound 50"),
                          ({"max_accel": float("nan")}, "quality max_accel is nan")):
        with pytest.raises(ClipOutOfBounds, match=words.replace("(", r"\(").replace(".", r"\.")):
            check_clip_bounds(t, {**fine, **change})
    t[1, 1, 5] = np.inf
    with pytest.raises(ClipOutOfBounds, match="1 transform values are NaN or infinite"):
        check_clip_bounds(t, fine)
    assert MAX_SECONDARY_MOTION_PCT == 50.0


@pytest.mark.slow
def test_apparel_with_an_absurd_link_mass_fails_its_clips_naming_the_bound(tmp_path):
    from mimicbench.datagen.apparel.params import load_params
    from mimicbench.datagen.apparel.stage import simulate_dataset
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import read_records

    zoo = tmp_path / "zoo"
    build_zoo(zoo, 1, seed=0, categories=["apparel"], clips_per_character=1, frames_per_clip=30, progress=False)
    heavy = tmp_path / "heavy.json"
    kinds = ("skirt", "hair", "ponytail", "cape", "coat_tail", "default")
    heavy.write_text(json.dumps({"kinds": {k: {"link_mass": 1000} for k in kinds}}))
    out = tmp_path / "sim"
    try:
        summary = simulate_dataset(zoo, out, params=load_params(heavy), progress=False)
        rows = summary["statuses"]
    except Exception as exc:  # every clip failed: the stage refuses to write a dataset, naming the reasons
        assert "is over the bound" in str(exc), exc
        assert not any(m.name.endswith("@sim") for m in read_records(out, "motions")) if out.exists() else True
        return
    failed = [s for s in rows if s.status == "failed"]
    assert failed and all("is over the bound" in s.reason for s in failed), rows
    assert not any(m.name.endswith("@sim") for m in read_records(out, "motions"))


# --- 16. under an address-space limit: correspond finishes, or fails naming the limit --------------------

def _correspond_under(limit_bytes: int, data: Path):
    import os
    import resource
    import subprocess
    import sys

    def limited():
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "ARROW_DEFAULT_MEMORY_POOL")}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    return subprocess.run([sys.executable, "-m", "mimicbench", "datagen", "correspond", str(data), "--quiet"],
                          capture_output=True, text=True, env=env, preexec_fn=limited, timeout=600)


def test_address_space_settings_follow_the_limit(monkeypatch):
    import resource

    from mimicbench.runtime import address_space

    monkeypatch.setattr(resource, "getrlimit", lambda what: (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    assert address_space.address_space_limit() is None and address_space.limit_text() == ""
    monkeypatch.setattr(resource, "getrlimit", lambda what: (3145728 * 1024, resource.RLIM_INFINITY))
    assert address_space.limit_text() == "the address-space limit (ulimit -v 3145728) of 3.0 GiB"
    for name in ("ARROW_DEFAULT_MEMORY_POOL", "MALLOC_ARENA_MAX", *address_space.THREAD_VARIABLES):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "2")  # a user's own setting wins
    assert address_space.fit_to_address_space_limit() == 3145728 * 1024
    import os

    assert os.environ["ARROW_DEFAULT_MEMORY_POOL"] == "system" and os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert os.environ["OMP_NUM_THREADS"] == "2" and os.environ["MALLOC_ARENA_MAX"] == "2"


@pytest.mark.slow
def test_correspond_under_a_3_gib_address_space_limit_finishes_and_under_1_gib_names_it(humanoids, tmp_path):
    import shutil

    from mimicbench.schemas.shards import read_records

    data = tmp_path / "data"
    shutil.copytree(humanoids, data)
    run = _correspond_under(3145728 * 1024, data)  # `ulimit -v 3145728`, as the probe
    assert run.returncode == 0, run.stderr[-2000:]
    assert len(read_records(data, "pairs")) == 6  # ordered pairs of the 3 test-split humanoids
    run = _correspond_under(2**30, data)
    assert run.returncode == 2
    assert "the address-space limit (ulimit -v 1048576) of 1.0 GiB is below the 1.75 GiB" in run.stderr, run.stderr


@pytest.mark.parametrize("content, needle", [('{"../../evil": ["assets/a"]}', "split name '../../evil'"),
                                             ('{"train": "assets/a"}', "expected a list of character IDs"),
                                             ('["assets/a"]', "expected a JSON object")])
def test_a_split_file_cannot_name_a_path(tmp_path, capsys, content, needle):
    from tests.mmd_fixtures import pmx_bytes

    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    (tmp_path / "splits.json").write_text(content)
    out = tmp_path / "sub" / "ds"
    assert main(["datagen", "ingest", str(tmp_path / "a.pmx"), "--out", str(out), "--split-file",
                 str(tmp_path / "splits.json"), "--quiet"]) == 2
    _one_line(capsys, needle)
    assert not (tmp_path / "evil-00000-of-00001.parquet").exists() and not out.exists()


def test_an_ingest_where_every_asset_fails_ends_with_its_summary_not_an_error(tmp_path, capsys):
    """The category report after ingest reads the characters table: when no asset made one, the
    summary is the last word and the exit status says some items failed."""
    from mimicbench.cli import main

    bad = tmp_path / "x.glb"
    bad.write_text("garbage")
    code = main(["datagen", "ingest", str(bad), "--out", str(tmp_path / "out")])
    out = capsys.readouterr()
    assert code == 1
    assert "0 characters and 0 clips" in out.out and "error" not in out.err
