"""mimicbench.runtime.registry.Registry: lazy entries, entry points, collisions, did-you-mean, load errors."""
from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import pytest

from mimicbench.runtime.registry import LoadError, NameCollision, Registry, UnknownName, load_target, parse_target
from mimicbench.schemas.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def fake_distribution(folder: Path, name: str, entries: dict[str, str], group: str = "mimicbench.methods") -> None:
    """An installed-looking distribution in ``folder`` (put it on sys.path) declaring ``entries``."""
    dist = folder / f"{name.replace('-', '_')}-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in entries.items()))


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    """A folder on sys.path holding module ``regtest_plugin`` (classes A and B); removed after the test."""
    (tmp_path / "regtest_plugin.py").write_text("class A:\n    pass\n\n\nclass B:\n    class Inner:\n        pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    sys.modules.pop("regtest_plugin", None)


def test_entries_are_imported_only_when_asked_for(plugin_dir):
    reg = Registry("thing", {"a": "regtest_plugin:A", "inner": "regtest_plugin:B.Inner"})
    assert reg.names() == ["a", "inner"] and "a" in reg and "zzz" not in reg
    assert "regtest_plugin" not in sys.modules
    assert reg.target("a") == "regtest_plugin:A" and "regtest_plugin" not in sys.modules
    a = reg.get("a")
    assert a.__name__ == "A" and a.__module__ == "regtest_plugin" and reg.get("a") is a
    assert reg.get("inner").__qualname__ == "B.Inner"


def test_unknown_name_says_what_is_close_and_what_exists():
    reg = Registry("method", {"name_copy": object, "identity": object, "nearest_joint": object})
    with pytest.raises(UnknownName) as info:
        reg.get("name_cpy")
    msg = str(info.value)
    assert msg == ("unknown method 'name_cpy'. Did you mean 'name_copy'? "
                   "Available: name_copy, identity, nearest_joint")
    assert isinstance(info.value, UserError) and isinstance(info.value, KeyError) and isinstance(info.value, ValueError)
    assert "Did you mean" not in str(pytest.raises(UnknownName, reg.get, "zzzz").value)


def test_runtime_registration_replaces_itself_but_never_a_builtin():
    class Mine:
        pass

    class Other:
        pass

    reg = Registry("protocol", {"h2h": Mine})
    reg.register("h2h", Mine)  # the same target: no collision
    reg.register("toy", Mine)
    reg.register("toy", Other)  # run time over run time: replaced
    assert reg.get("toy") is Other and reg.names() == ["h2h", "toy"]
    with pytest.raises(NameCollision, match="protocol 'h2h': a built-in already has that name"):
        reg.register("h2h", Other)
    assert reg.get("h2h") is Mine


def test_entry_points_join_and_a_different_target_under_a_builtin_name_collides(plugin_dir, tmp_path):
    reg = Registry("method", {"a": "regtest_plugin:A"}, group="regtest.methods")
    fake_distribution(tmp_path / "one", "regtest-one", {"a": "regtest_plugin:A", "plug": "regtest_plugin:B"},
                      "regtest.methods")
    sys.path.insert(0, str(tmp_path / "one"))
    try:
        assert reg.names() == ["a", "plug"]
        assert reg.get("a").__name__ == "A"  # the built-in declared again with the same target is fine
        assert reg.get("plug").__name__ == "B"
        fake_distribution(tmp_path / "two", "regtest-two", {"a": "regtest_plugin:B"}, "regtest.methods")
        sys.path.insert(0, str(tmp_path / "two"))
        with pytest.raises(NameCollision, match="two installed packages declare it"):
            reg.get("a")
        sys.path.remove(str(tmp_path / "one"))
        with pytest.raises(NameCollision, match="entry point regtest_plugin:B .* collides with the built-in "
                                                "regtest_plugin:A"):
            reg.get("a")
    finally:
        for p in (tmp_path / "one", tmp_path / "two"):
            if str(p) in sys.path:
                sys.path.remove(str(p))


def test_an_entry_that_cannot_be_imported_is_a_load_error_naming_it(plugin_dir):
    reg = Registry("method", {"gone": "regtest_missing_module:Thing", "typo": "regtest_plugin:C", "bad": "no colon"})
    with pytest.raises(LoadError, match=r"method 'gone': cannot load regtest_missing_module:Thing "
                                        r"\(ModuleNotFoundError: No module named 'regtest_missing_module'\)"):
        reg.get("gone")
    with pytest.raises(LoadError, match="AttributeError"):
        reg.get("typo")
    with pytest.raises(LoadError, match="expected 'package.module:attr'"):
        reg.get("bad")


def test_parse_target_by_hand():
    assert parse_target("a.b:C.D") == ("a.b", "C.D")
    for bad in ("a.b", ":C", "a.b:", "a b:C", "a.b:C-D"):
        with pytest.raises(ValueError, match="package.module:attr"):
            parse_target(bad)
    assert load_target("os.path:join") is __import__("os").path.join


def test_pyproject_entry_points_are_the_bundled_methods_and_models():
    """Each entry point in pyproject.toml (read as TOML here) names a class under mimicbench.baselines whose
    metadata carries the same name, and the registries list exactly those names."""
    from mimicbench.benchmark.method import PoseTransferLike
    from mimicbench.benchmark.registry import METHODS
    from mimicbench.training.registry import TRAINABLES

    groups = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    methods, models = groups["mimicbench.methods"], groups["mimicbench.trainables"]
    assert {"identity", "nearest_joint", "mimicat", "npt", "cgt", "sfpt", "probe_mirror"} <= set(methods)
    assert set(models) == {"mimicat", "mmdmc", "npt", "cgt", "sfpt"}
    for name, target in methods.items():
        assert target.startswith("mimicbench.baselines."), target
        method = load_target(target)()
        assert isinstance(method, PoseTransferLike) and method.metadata.name == name
    for name, target in models.items():
        assert target == f"mimicbench.baselines.{name}.training:TRAINABLE"
        assert load_target(target).name == name
    assert set(METHODS.names()) >= set(methods) and set(TRAINABLES.names()) >= set(models)


def test_every_registry_resolves_its_builtins_without_installed_metadata(monkeypatch):
    """Built-ins come from code: with no entry points at all, protocols, matchers, encoders and engines still
    find their names; methods and trainable models are entry points only, so none is found."""
    import mimicbench.runtime.registry as registry
    from mimicbench.benchmark.protocols import get_protocol
    from mimicbench.benchmark.registry import get_method
    from mimicbench.datagen.correspond.encoders import ENCODERS, ClipEncoder
    from mimicbench.datagen.correspond.methods import get_matcher
    from mimicbench.engines import LocalEngine, get_engine
    from mimicbench.training.registry import trainable

    monkeypatch.setattr(registry, "entry_points", lambda group: [])
    for lookup, name in ((get_method, "name_copy"), (trainable, "mmdmc")):
        with pytest.raises(UnknownName):
            lookup(name)
    assert get_protocol("cct").name == "cct"
    assert get_matcher("text").name == "text"
    assert ENCODERS.get("clip") is ClipEncoder
    assert isinstance(get_engine("local", 1), LocalEngine)
    for lookup, name, kind in ((get_protocol, "ctt", "protocol"), (get_matcher, "structur", "matching method"),
                               (get_engine, "rey", "engine")):
        with pytest.raises(UnknownName, match=f"unknown {kind} '{name}'. Did you mean"):
            lookup(name)
