"""``mimicat`` and its ablations through the benchmark registry, with the shipped checkpoint."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from baselines.mimicat.method import BUNDLED, Mimicat
from benchmark.registry import available_methods, get_method
from tests.mimicat_toys import request, tube_rig

STAGES = ("shape", "corr", "transfer", "transfer_no_prior")


@pytest.fixture(scope="module")
def requests():
    rigs = [tube_rig("a", 3), tube_rig("b", 5, 1.4), tube_rig("c", 4, 0.7, branch=False)]
    return [request(rigs[0], rigs[1], 0), request(rigs[1], rigs[2], 1), request(rigs[2], rigs[0], 2)]


def test_shipped_checkpoint_is_small_and_complete():
    total = 0
    for stage in STAGES:
        path = BUNDLED / f"{stage}.safetensors"
        assert path.is_file(), f"missing shipped weights {path}"
        total += path.stat().st_size
    assert total < 8 * 2**20  # a few MB, shipped in the package


def test_registered_names_answer_mixed_batches(requests):
    assert {"mimicat", "mimicat_naive_avg", "mimicat_no_prior"} <= set(available_methods())
    outputs = {}
    for name in ("mimicat", "mimicat_naive_avg", "mimicat_no_prior"):
        method = get_method(name)
        assert method.metadata.name == name and set(method.metadata.protocols) == {"h2h", "cct"}
        method.setup("cpu")
        out = method.transfer(requests)
        for r, v in zip(requests, out):
            assert v.shape == (len(r.target.vertices), 3) and v.dtype == np.float32
            assert np.isfinite(v).all()
        outputs[name] = out
    # the ablations are different models: some answer differs from the full model's
    for name in ("mimicat_naive_avg", "mimicat_no_prior"):
        assert max(np.abs(a - b).max() for a, b in zip(outputs[name], outputs["mimicat"])) > 1e-6


def test_batching_does_not_change_answers(requests):
    method = Mimicat(arap=False, batch_size=1)
    one_by_one = method.transfer(requests)
    together = Mimicat(arap=False, batch_size=16).transfer(requests)
    for a, b in zip(one_by_one, together):
        np.testing.assert_allclose(a, b, atol=1e-4)


def test_checkpoint_option_run_layout_and_errors(tmp_path, requests, monkeypatch):
    run = tmp_path / "run"
    for stage in STAGES:
        (run / stage).mkdir(parents=True)
        shutil.copy(BUNDLED / f"{stage}.safetensors", run / stage / "model.safetensors")
    expected = Mimicat(arap=False).transfer(requests[:1])[0]
    np.testing.assert_allclose(Mimicat(run, arap=False).transfer(requests[:1])[0], expected, atol=1e-6)
    monkeypatch.setenv("MIMICAT_CHECKPOINT", str(run))
    assert Mimicat().checkpoint == run
    with pytest.raises(FileNotFoundError, match="no weights for stage 'shape'"):
        Mimicat(tmp_path / "empty").setup("cpu")
