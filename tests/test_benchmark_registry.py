import sys

import pytest

from mimicbench.benchmark.method import PoseTransferMethod
from mimicbench.benchmark.registry import UnknownName, available_methods, get_method, register
from mimicbench.cli import main
from tests.bench_fixtures import make_bench_dataset
from tests.bench_fixtures import FlakyMethod
from tests.test_registry import fake_distribution


def test_bundled_methods_load_lazily_with_metadata():
    names = available_methods()
    assert {"identity", "name_copy", "nearest_joint", "text_soft"} <= set(names)
    m = get_method("name_copy")
    assert isinstance(m, PoseTransferMethod) and m.metadata.name == "name_copy" and m.metadata.version


def test_unknown_name_suggests_close_matches():
    with pytest.raises(UnknownName, match=r"Did you mean 'name_copy'"):
        get_method("name_cpy")
    with pytest.raises(UnknownName, match="Available: "):
        get_method("zzzz")


def test_runtime_registration_and_entry_points(tmp_path, monkeypatch):
    import mimicbench.benchmark.registry as registry

    monkeypatch.setattr(registry.METHODS, "_runtime", dict(registry.METHODS._runtime))  # names registered here stay here
    register("flaky", FlakyMethod)
    assert isinstance(get_method("flaky"), FlakyMethod)
    # a third-party package declaring `mimicbench.methods` in its entry points
    pkg = tmp_path / "thirdparty_pose.py"
    pkg.write_text("from mimicbench.baselines.identity import Identity\nclass Mine(Identity):\n    pass\n")
    dist = tmp_path / "thirdparty_pose-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: thirdparty-pose\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[mimicbench.methods]\nmy_method = thirdparty_pose:Mine\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "my_method" in available_methods()
    assert type(get_method("my_method")).__name__ == "Mine"
    sys.modules.pop("thirdparty_pose", None)


def test_a_typo_in_methods_is_one_error_line_naming_the_close_match_exit_2(tmp_path, capsys, monkeypatch):
    import mimicbench.benchmark.registry as registry

    monkeypatch.setattr(registry.METHODS, "_runtime", {})  # only the bundled names (other tests register more)
    code = main(["bench", "run", str(tmp_path / "D"), "--methods", "identity,name_cpy", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    lines = [x for x in err.splitlines() if "name_copy" in x]
    assert len(lines) == 1 and lines[0].startswith("mimicbench: error: unknown method 'name_cpy'. Did you mean "
                                                   "'name_copy'?")
    assert not (tmp_path / "r").exists()


@pytest.fixture
def broken_plugin(tmp_path, monkeypatch):
    """An installed plug-in whose entry point imports a module that is not there."""
    fake_distribution(tmp_path / "site", "broken_pose", {"broken_pose": "broken_pose_missing.module:Method"})
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    return "broken_pose"


def test_bench_methods_lists_the_others_and_names_the_broken_entry_point(broken_plugin, capsys):
    code = main(["bench", "methods"])
    out, err = capsys.readouterr()
    listed = [line.split()[0] for line in out.splitlines()]
    assert code == 1 and {"identity", "name_copy", "mmdmc", "mimicat"} <= set(listed) and broken_plugin not in listed
    assert err.splitlines()[0] == ("mimicbench: error: method 'broken_pose': cannot load broken_pose_missing.module:"
                                   "Method (ModuleNotFoundError: No module named 'broken_pose_missing')")


def test_a_broken_method_is_left_out_and_the_others_run(broken_plugin, small_zoo, tmp_path, capsys):
    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=1, cct_pairs=2, cct_poses=1)
    out = tmp_path / "res"
    code = main(["bench", "run", str(data), "--methods", f"{broken_plugin},identity", "--out", str(out), "--quiet",
                 "--in-process"])
    stdout, err = capsys.readouterr()
    assert code == 1
    assert ("mimicbench: error: not run: method 'broken_pose': cannot load broken_pose_missing.module:Method "
            "(ModuleNotFoundError: No module named 'broken_pose_missing')") in err.splitlines()
    assert (out / "identity").is_dir() and not (out / broken_plugin).exists()
    assert "identity" in stdout and "0 failed" in stdout


def test_published_baselines_are_registered_with_their_papers_and_protocols():
    from mimicbench.training.registry import available_trainables, trainable

    expected = {"npt": ("h2h", "cct"), "cgt": ("h2h", "cct"), "sfpt": ("h2h", "cct", "apparel")}
    for name, protocols in expected.items():
        meta = get_method(name).metadata
        assert meta.name == name and meta.licence.startswith("MIT") and meta.needs_training
        assert "re-implemented from the paper" in meta.citation and meta.protocols == protocols
        stages = [s.name for s in trainable(name).stages]  # sfpt: its joint stage, then the pose decoder alone
        assert name in available_trainables() and stages == ([name, "decoder"] if name == "sfpt" else [name])
        assert {"cpu", "paper"} <= set(trainable(name).configs)
    assert "non-commercial" in get_method("sfpt").metadata.licence  # the original code and weights'
    for name, base in (("npt_constant_code", "npt"), ("cgt_no_attention", "cgt"), ("sfpt_kabsch_only", "sfpt")):
        meta = get_method(name).metadata  # the ablations: registered, their base's licence and protocols
        assert meta.name == name and meta.licence == get_method(base).metadata.licence
        assert meta.protocols == expected[base] and "ablation" in meta.tags
