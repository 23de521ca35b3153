"""``mimicbench zoo`` options: categories, clips per character, errors, help."""
import pytest

from mimicbench.cli import build_parser, main
from mimicbench.schemas.manifest import load_manifest
from mimicbench.schemas.shards import read_records


def test_categories_and_clip_count(tmp_path, capsys):
    out = tmp_path / "z"
    assert main(["zoo", "--out", str(out), "--characters", "3", "--categories", "fish", "insect",
                 "--clips-per-character", "4", "--seed", "5", "--quiet"]) == 0
    chars = read_records(out, "characters")
    assert sorted(c.category for c in chars) == ["fish", "fish", "insect"]
    motions = read_records(out, "motions")
    assert len(motions) == 12
    assert {m.name for m in motions if m.character_id.startswith("zoo/fish")} == {
        "swim", "idle", "random_poses", "random_poses_2"}
    config = load_manifest(out)["configs"]["characters"]
    assert config["seed"] == 5 and config["categories"] == ["fish", "insect"]
    assert "3 characters" in capsys.readouterr().out


def test_comma_separated_categories_and_unknown_category(tmp_path, capsys):
    out = tmp_path / "z"
    assert main(["zoo", "--out", str(out), "--characters", "2", "--categories", "bird,reptile", "--quiet"]) == 0
    assert sorted(c.category for c in read_records(out, "characters")) == ["bird", "reptile"]
    assert main(["zoo", "--out", str(out), "--characters", "2", "--categories", "dragon", "--quiet"]) == 2
    assert "mimicbench: error: categories: unknown ['dragon']" in capsys.readouterr().err


def test_unknown_export_format_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["zoo", "--out", str(tmp_path / "z"), "--characters", "1", "--export", "fbx", "--quiet"])
    assert exc.value.code == 2
    assert "mimicbench: error: argument --export: unknown 'fbx'" in capsys.readouterr().err
    assert not (tmp_path / "z").exists()


def test_help_teaches_with_an_example(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["zoo", "--help"])
    text = capsys.readouterr().out
    assert "mimicbench zoo --out data/zoo --characters 40 --seed 0" in text
