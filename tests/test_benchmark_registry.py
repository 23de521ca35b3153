import sys

import pytest

from benchmark.method import PoseTransferMethod
from benchmark.registry import available_methods, get_method, register
from tests.bench_fixtures import FlakyMethod


def test_bundled_methods_load_lazily_with_metadata():
    names = available_methods()
    assert {"identity", "name_copy", "nearest_joint", "text_soft"} <= set(names)
    m = get_method("name_copy")
    assert isinstance(m, PoseTransferMethod) and m.metadata.name == "name_copy" and m.metadata.version


def test_unknown_name_suggests_close_matches():
    with pytest.raises(KeyError, match=r"Did you mean 'name_copy'"):
        get_method("name_cpy")
    with pytest.raises(KeyError, match="Available: "):
        get_method("zzzz")


def test_runtime_registration_and_entry_points(tmp_path, monkeypatch):
    import benchmark.registry as registry

    monkeypatch.setattr(registry, "_registered", dict(registry._registered))  # names registered here stay here
    register("flaky", FlakyMethod)
    assert isinstance(get_method("flaky"), FlakyMethod)
    # a third-party package declaring `mimicbench.methods` in its entry points
    pkg = tmp_path / "thirdparty_pose.py"
    pkg.write_text("from baselines.identity import Identity\nclass Mine(Identity):\n    pass\n")
    dist = tmp_path / "thirdparty_pose-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: thirdparty-pose\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[mimicbench.methods]\nmy_method = thirdparty_pose:Mine\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "my_method" in available_methods()
    assert type(get_method("my_method")).__name__ == "Mine"
    sys.modules.pop("thirdparty_pose", None)


def test_published_baselines_are_registered_with_their_papers_and_protocols():
    from mimicbench.training.registry import available_trainables, trainable

    expected = {"npt": ("h2h", "cct"), "cgt": ("h2h", "cct"), "sfpt": ("h2h", "cct", "apparel")}
    for name, protocols in expected.items():
        meta = get_method(name).metadata
        assert meta.name == name and meta.licence == "MIT" and meta.needs_training
        assert "re-implemented from the paper" in meta.citation and meta.protocols == protocols
        assert name in available_trainables() and [s.name for s in trainable(name).stages] == [name]
        assert {"small", "paper"} <= set(trainable(name).configs)
