"""The one trainer: loss goes down, seeds repeat, checkpoints round-trip and resume, torchrun matches."""
from __future__ import annotations

import copy
import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from mimicbench.training import checkpoint
from mimicbench.training.batching import rank_batches
from mimicbench.training.loop import seed_everything, train_model, train_stage
from mimicbench.schemas.errors import UserError
from tests import training_toys

REPO = Path(__file__).resolve().parents[1]


def config(**fit):
    c = copy.deepcopy(training_toys.CONFIG)
    c["fit"].update(fit)
    return c


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return training_toys.write_toy_dataset(tmp_path_factory.mktemp("toy"))


def weights(path):
    state, _ = checkpoint.load_checkpoint(path)
    return state


def test_loss_goes_down_and_logs(data, tmp_path):
    path = train_stage("toy", "fit", data, tmp_path, config(), epochs=8, seed=0, progress=False)
    with open(tmp_path / "fit" / "loss.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 8 * (96 // 16)  # one row a step
    assert rows[0]["epoch"] == "0" and rows[-1]["epoch"] == "7" and {"total", "mae"} <= set(rows[0])
    first = np.mean([float(r["total"]) for r in rows if r["epoch"] == "0"])
    last = np.mean([float(r["total"]) for r in rows if r["epoch"] == "7"])
    assert last < 0.5 * first
    # the final weights reproduce the last logged loss's order of magnitude on the whole data set
    module = checkpoint.load_module(path, lambda cfg: training_toys._build_fit(cfg, None))
    d = np.load(data / "toy.npz")
    with torch.no_grad():
        mse = float(((module(torch.from_numpy(d["x"])) - torch.from_numpy(d["y"])) ** 2).mean())
    assert mse < first * 0.5
    img = Image.open(tmp_path / "fit" / "loss.png")
    assert img.size[0] > 200 and np.asarray(img.convert("L")).std() > 5  # a drawn, non-blank plot
    assert (tmp_path / "config.json").is_file()


def test_same_seed_same_weights_other_seed_differs(data, tmp_path):
    a = weights(train_stage("toy", "fit", data, tmp_path / "a", config(), epochs=2, seed=5, progress=False))
    b = weights(train_stage("toy", "fit", data, tmp_path / "b", config(), epochs=2, seed=5, progress=False))
    c = weights(train_stage("toy", "fit", data, tmp_path / "c", config(), epochs=2, seed=6, progress=False))
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_checkpoint_round_trip_and_header(data, tmp_path):
    path = train_stage("toy", "fit", data, tmp_path, config(), epochs=1, seed=0, progress=False)
    header = checkpoint.read_header(path)
    assert header["model"] == "toy" and header["stage"] == "fit" and header["epoch"] == 1
    assert header["config"] == config() and header["seed"] == 0 and "torch" in header
    module = checkpoint.load_module(path, lambda cfg: training_toys._build_fit(cfg, None))
    raw = weights(path)
    assert all(torch.equal(module.state_dict()[k], raw[k]) for k in raw)
    assert not module.training
    # the resume state loads with weights_only=True and holds the optimizer's moments
    state = checkpoint.load_state(checkpoint.find_resume(tmp_path / "fit")[1])
    assert state["epoch"] == 1 and state["optimizer"]["state"]
    # a build of other shapes is refused with a message naming the checkpoint
    with pytest.raises(ValueError, match="do not fit"):
        checkpoint.load_module(path, lambda cfg: training_toys._build_fit({"fit": {"width": 8}}, None))


def test_resume_continues_exactly(data, tmp_path):
    full = weights(train_stage("toy", "fit", data, tmp_path / "full", config(), epochs=4, seed=1, progress=False))
    train_stage("toy", "fit", data, tmp_path / "cut", config(), epochs=2, seed=1, progress=False)
    resumed = weights(train_stage("toy", "fit", data, tmp_path / "cut", config(), epochs=4, seed=1, progress=False))
    assert all(torch.equal(full[k], resumed[k]) for k in full)
    with open(tmp_path / "cut" / "fit" / "loss.csv") as f:
        rows = list(csv.DictReader(f))
    with open(tmp_path / "full" / "fit" / "loss.csv") as f:
        rows_full = list(csv.DictReader(f))
    assert rows == rows_full
    # another config on the same run folder is refused, nothing overwritten
    before = checkpoint.find_resume(tmp_path / "cut" / "fit")[0].read_bytes()
    with pytest.raises(UserError, match="with another config; "):
        train_stage("toy", "fit", data, tmp_path / "cut", config(width=16, epochs=3) | {"lr": 0.5}, epochs=5,
                    seed=1, progress=False)
    assert checkpoint.find_resume(tmp_path / "cut" / "fit")[0].read_bytes() == before


def test_needs_are_loaded_frozen(data, tmp_path):
    with pytest.raises(UserError, match="train it first"):
        train_stage("toy", "head", data, tmp_path, config(), epochs=1, progress=False)
    results = train_model("toy", "all", data, tmp_path, config(), epochs=1, progress=False)
    assert [r.stage for r in results] == ["fit", "head"]
    fit_before = weights(tmp_path / "fit" / "model.safetensors")
    head = weights(tmp_path / "head" / "model.safetensors")
    assert set(head) == {"weight", "bias"}  # only the head is in the head stage's checkpoint
    assert all(torch.equal(fit_before[k], weights(tmp_path / "fit" / "model.safetensors")[k]) for k in fit_before)


def test_rank_batches_partition_the_global_batches():
    rng = lambda: np.random.default_rng([4, 0])  # noqa: E731
    one = rank_batches(50, 8, rng())
    two = [rank_batches(50, 8, rng(), r, 2) for r in range(2)]
    assert len(one) == 6 and all(len(b) == 8 for b in one)  # 50 // 8 full batches, the rest dropped
    assert len(two[0]) == len(two[1]) == 6
    for i in range(6):
        assert sorted(np.concatenate([two[0][i], two[1][i]])) == sorted(one[i])
        assert not set(two[0][i]) & set(two[1][i])
    seen = np.concatenate(one)
    assert len(set(seen)) == 48
    with pytest.raises(ValueError):
        rank_batches(1, 8, rng(), 0, 2)


def test_cli_train_summary(data, tmp_path, capsys):
    from mimicbench.cli import main

    rc = main(["train", "toy", str(data), "--out", str(tmp_path), "--stage", "fit", "--epochs", "1",
               "--set", "fit.width=8", "--no-progress"])
    out = capsys.readouterr().out
    assert rc == 0 and "fit" in out and "model.safetensors" in out and "total" in out
    assert checkpoint.read_header(tmp_path / "fit" / "model.safetensors")["config"]["fit"]["width"] == 8
    assert main(["train", "toy", str(data), "--out", str(tmp_path), "--set", "fit.wdth=8"]) == 2
    assert "unknown key" in capsys.readouterr().err
    assert main(["train", "tyo", str(data), "--out", str(tmp_path)]) == 2
    assert "Did you mean 'toy'" in capsys.readouterr().err


@pytest.mark.slow
def test_torchrun_two_processes_match_one(data, tmp_path):
    """2 gloo ranks, each with half of every global batch, end where 1 process with the whole batch ends."""
    one = weights(train_stage("toy", "fit", data, tmp_path / "one", config(), epochs=1, seed=3, progress=False))
    env = {**os.environ, "PYTHONPATH": str(REPO), "OMP_NUM_THREADS": "1"}
    torchrun = Path(sys.executable).with_name("torchrun")
    proc = subprocess.run([str(torchrun), "--standalone", "--nproc-per-node", "2",
                           str(REPO / "tests" / "training_ddp_child.py"), str(data), str(tmp_path / "two")],
                          env=env, capture_output=True, text=True, timeout=300, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-3000:]
    two = weights(tmp_path / "two" / "fit" / "model.safetensors")
    seed_everything(3)
    init = training_toys._build_fit(config(), None)  # the weights moved: the test compares trained weights
    assert any(not torch.allclose(two[k], v) for k, v in init.state_dict().items())
    for k in one:
        torch.testing.assert_close(two[k], one[k], rtol=1e-5, atol=1e-6)
    with open(tmp_path / "two" / "fit" / "loss.csv") as f:
        assert len(list(csv.DictReader(f))) == 96 // 16
    assert (tmp_path / "two" / "head" / "model.safetensors").is_file()  # the second stage ran under the same group


def test_cli_threads_sets_torch_threads_before_training(data, tmp_path, capsys, monkeypatch):
    from mimicbench.cli import main
    from mimicbench.training import loop

    seen = []
    real = loop.train_model

    def spy(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return real(*args, **kwargs)

    before = torch.get_num_threads()
    monkeypatch.setattr(loop, "train_model", spy)
    try:
        torch.set_num_threads(2)
        assert main(["train", "toy", str(data), "--out", str(tmp_path), "--stage", "fit", "--epochs", "1",
                     "--set", "fit.width=8", "--no-progress", "--threads", "1"]) == 0
        assert seen == [1]
        assert main(["train", "toy", str(data), "--out", str(tmp_path / "b"), "--threads", "0"]) == 2
        assert "--threads" in capsys.readouterr().err and seen == [1]
    finally:
        torch.set_num_threads(before)


def _flip(path: Path, offset: int) -> None:
    data = bytearray(path.read_bytes())
    data[offset] ^= 0xFF
    path.write_bytes(bytes(data))


def _zip_member_offset(path: Path, suffix: str) -> tuple[int, int]:
    """(offset, size) of a stored member's data in a zip file, from its local header (APPNOTE 4.3.7)."""
    import struct
    import zipfile

    with zipfile.ZipFile(path) as z:
        info = next(i for i in z.infolist() if i.filename.endswith(suffix))
    raw = path.read_bytes()
    name_len, extra_len = struct.unpack_from("<HH", raw, info.header_offset + 26)
    return info.header_offset + 30 + name_len + extra_len, info.compress_size


def test_corrupt_checkpoints_are_refused_before_resume(data, tmp_path):
    """Issue 31 item 8: a flipped byte in last.safetensors' tensor data, in an optimizer tensor or
    in the pickle part of state.pt is refused with a one-line error, never resumed from."""
    import hashlib
    import json
    import struct

    run = tmp_path / "run"
    train_stage("toy", "fit", data, run, config(), epochs=1, seed=1, progress=False)
    last, state = checkpoint.find_resume(run / "fit")
    for path in (last, state, run / "fit" / "model.safetensors"):  # digest files in sha256sum's format
        digest = checkpoint.digest_path(path).read_text()
        assert digest == f"{hashlib.sha256(path.read_bytes()).hexdigest()}  {path.name}\n"
    pristine = {p: p.read_bytes() for p in (last, state)}
    header_len = struct.unpack_from("<Q", pristine[last])[0]  # safetensors: 8-byte header length, JSON, data
    _flip(last, 8 + header_len + 5)
    with pytest.raises(UserError, match=r"last\.safetensors: sha256 .* does not match last\.safetensors\.sha256"):
        train_stage("toy", "fit", data, run, config(), epochs=2, seed=1, progress=False)
    last.write_bytes(pristine[last])
    offset, size = _zip_member_offset(state, "/data/0")  # the first tensor: an optimizer moment
    _flip(state, offset + size // 2)
    with pytest.raises(UserError, match=r"state\.pt: sha256 .* does not match"):
        train_stage("toy", "fit", data, run, config(), epochs=2, seed=1, progress=False)
    # a damaged pickle part whose digest was recomputed still gives one line, not a traceback
    state.write_bytes(pristine[state])
    offset, size = _zip_member_offset(state, "data.pkl")
    _flip(state, offset + 2)
    checkpoint.digest_path(state).write_text(f"{hashlib.sha256(state.read_bytes()).hexdigest()}  state.pt\n")
    record = json.loads((run / "fit" / checkpoint.RESUME_FILE).read_text())
    record["sha256"]["state.pt"] = hashlib.sha256(state.read_bytes()).hexdigest()
    (run / "fit" / checkpoint.RESUME_FILE).write_text(json.dumps(record))
    with pytest.raises(UserError, match=r"state\.pt: not a readable resume state"):
        train_stage("toy", "fit", data, run, config(), epochs=2, seed=1, progress=False)
    garbled = tmp_path / "garbled.safetensors"
    garbled.write_bytes(struct.pack("<Q", 40) + b"{not json" + b" " * 31)
    with pytest.raises(UserError, match="garbled.safetensors: not a readable safetensors checkpoint"):
        checkpoint.load_checkpoint(garbled)
    # a missing digest is refused too; the untouched files resume as before
    state.write_bytes(pristine[state])
    checkpoint.digest_path(state).unlink()
    with pytest.raises(UserError, match=r"no state\.pt\.sha256 beside it"):
        train_stage("toy", "fit", data, run, config(), epochs=2, seed=1, progress=False)
    checkpoint.digest_path(state).write_text(f"{hashlib.sha256(pristine[state]).hexdigest()}  state.pt\n")
    record["sha256"]["state.pt"] = hashlib.sha256(pristine[state]).hexdigest()
    (run / "fit" / checkpoint.RESUME_FILE).write_text(json.dumps(record))
    resumed = weights(train_stage("toy", "fit", data, run, config(), epochs=2, seed=1, progress=False))
    full = weights(train_stage("toy", "fit", data, tmp_path / "full", config(), epochs=2, seed=1, progress=False))
    assert all(torch.equal(full[k], resumed[k]) for k in full)
    assert json.loads((run / "config.json").read_text()) == config()
