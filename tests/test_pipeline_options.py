"""Each command's options as a dataclass filled by argparse or by a pipeline file; the pipeline calls
the stage functions with it (no command line in between) and reads the summary they return."""
from __future__ import annotations

import argparse
import dataclasses

import pyarrow.parquet as pq
import pytest

from mimicbench.cli import build_parser, command_parser, main
from mimicbench.runtime.options import from_mapping, from_namespace, options_class
from mimicbench.pipeline import load_pipeline, run_pipeline, step_options
from mimicbench.runtime.summary import StageSummary

HEAD = "[pipeline]\nname = 'p'\n"
ZOO = "[[steps]]\nrun = 'zoo'\nout = 'zoo'\ncharacters = 3\nclips_per_character = 1\nframes_per_clip = 12\n" \
      "no_contact_sheet = true\nquiet = true\n"


def test_the_options_dataclass_has_the_parsers_defaults_and_both_fillers_agree():
    from mimicbench.datagen.resample.params import ResampleParams

    parser = command_parser(("datagen", "resample"))
    cls = options_class(parser)
    assert cls is ResampleParams  # the stage's own params: the parser is made from it
    fields = {f.name: f.default for f in dataclasses.fields(cls)}
    assert fields == {"in_dataset": dataclasses.MISSING, "out_dataset": dataclasses.MISSING, "faces": 5000,
                      "backend": "fast", "jobs": 1, "engine": "local", "ray_address": None, "quiet": False}
    argv = ["datagen", "resample", "a", "b", "--faces", "800", "--backend", "pymeshlab", "--jobs", "2"]
    from_cli = from_namespace(parser, build_parser().parse_args(argv))
    from_file = from_mapping(parser, {"in_dataset": "a", "out_dataset": "b", "faces": 800, "backend": "pymeshlab",
                                      "jobs": 2}, "here")
    assert from_cli == from_file == cls(in_dataset="a", out_dataset="b", faces=800, backend="pymeshlab", jobs=2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        from_file.faces = 1
    zoo = command_parser(("zoo",))  # nargs="+": a list, or one string as one item; a comma type: a list joined
    assert from_mapping(zoo, {"out": "z", "categories": "fish"}, "here").categories == ["fish"]
    assert from_mapping(zoo, {"out": "z", "categories": ["fish", "bird"], "export": ["obj", "bvh"]}, "here") == \
        from_namespace(zoo, build_parser().parse_args(["zoo", "--out", "z", "--categories", "fish", "bird",
                                                       "--export", "obj,bvh"]))


def test_a_stage_function_called_with_its_dataclass_returns_its_summary(tmp_path):
    parser = command_parser(("zoo",))
    options = options_class(parser)(out=str(tmp_path / "zoo"), num_characters=3, clips_per_character=1,
                                    frames_per_clip=12, no_contact_sheet=True, quiet=True)
    summary = parser.get_default("func")(options)
    assert isinstance(summary, StageSummary)
    assert (summary.ok, summary.failed, summary.exit_code, summary.out) == (3, 0, 0, str(tmp_path / "zoo"))
    assert summary.seconds > 0
    rows = sum(pq.ParquetFile(p).metadata.num_rows for p in (tmp_path / "zoo" / "characters").rglob("*.parquet"))
    assert rows == 3  # counted from the shards themselves


def test_the_pipeline_calls_stages_without_a_command_line(tmp_path, monkeypatch):
    path = tmp_path / "p.toml"
    path.write_text(HEAD + ZOO)
    pipeline = load_pipeline(path, workdir=tmp_path / "w")
    pipeline.jobs = 2  # the pipeline's setting reaches the step's options
    assert step_options(pipeline.steps[0], pipeline)[1].jobs == 2
    pipeline.jobs = 1

    def no_argv(*args, **kwargs):
        raise AssertionError("the pipeline parsed a command line")

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", no_argv)
    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", no_argv)
    monkeypatch.setattr("mimicbench.cli.main", no_argv)
    [result] = run_pipeline(pipeline, progress=False)
    assert result.status == "done" and (result.summary.ok, result.summary.failed) == (3, 0)
    assert result.summary.out == str(tmp_path / "w" / "zoo") and "3 ok, 0 failed" in result.note
    [again] = run_pipeline(pipeline, progress=False)
    assert again.status == "skipped"


@pytest.mark.parametrize("step, message", [
    ("run = 'zoo'\nout = 'z'\ncharacters = 'many'\n", "characters = 'many' is a string; expected an integer"),
    ("run = 'zoo'\nout = 'z'\ncharacters = true\n", "characters = True is true or false; expected an integer"),
    ("run = 'zoo'\nout = 'z'\nquiet = 'yes'\n", "quiet = 'yes' is a string; expected true or false"),
    ("run = 'resample'\nin = 'a'\nout = 'b'\nfaces = 5000.5\n", "faces = 5000.5 is a number; expected an integer"),
    ("run = 'resample'\nin = 'a'\nout = 'b'\nfaces = 10\n", "faces = 10: expected an integer >= "),
    ("run = 'resample'\nin = 'a'\nout = 'b'\nbackend = 'slow'\n", "backend = 'slow': expected one of fast, pymeshlab"),
    ("run = 'resample'\nin = 'a'\nout = 'b'\nfacez = 900\n", "unknown option 'facez' (did you mean faces?)"),
    ("run = 'correspond'\ndataset = 'a'\npairs = 5\nall_pairs = true\n", "pairs and all_pairs cannot be used"),
    ("run = 'bench'\ndataset = 'a'\n", "missing methods"),
    ("run = 'bench'\ndataset = 'a'\nmethods = [{a = 1}]\n", "expected a list of strings or numbers"),
])
def test_a_wrong_option_is_refused_before_anything_runs(tmp_path, capsys, step, message):
    path = tmp_path / "p.toml"
    path.write_text(HEAD + ZOO + "[[steps]]\nname = 'second'\n" + step)  # the zoo step first: it must not run
    assert main(["pipeline", str(path), "--workdir", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: step 2 (" in err and message in err, err
    assert not (tmp_path / "w").exists()


def test_a_summary_says_its_exit_status():
    assert StageSummary(5).exit_code == 0 and StageSummary(5, 1).exit_code == 1
    assert StageSummary(5, 1, exit_code=0).exit_code == 0  # bench run: failed cases are results, not an error


def test_the_demo_is_its_bundled_pipeline_file_and_its_help_states_the_files_values():
    import re

    from mimicbench.commands.demo import DEMO_PIPELINE, OPTION_STEPS

    pipeline = load_pipeline(DEMO_PIPELINE, workdir="demo-output")  # every step's options checked
    steps = {s.name: s for s in pipeline.steps}
    helps = {a.dest: a.help or "" for a in command_parser(("demo",))._actions}
    for option, names in OPTION_STEPS.items():
        stated = re.search(r"\(default (\d+)\)", helps[option])  # "zoo size (default 16)"
        values = {steps[n].options[option] for n in names}
        assert len(values) == 1 and (stated is None or int(stated.group(1)) == values.pop()), option
    assert [s.kind for s in pipeline.steps] == ["zoo", "resample", "correspond", "cases", "bench", "apparel", "cases",
                                                "bench", "leaderboard", "leaderboard"]


def test_a_restart_step_starts_its_folder_again_when_its_inputs_changed(tmp_path):
    path = tmp_path / "p.toml"
    board = "[[steps]]\nname = '{0}'\nrun = 'leaderboard'\nresults = 'zoo'\nout = '{0}'\nno_pictures = true\n"
    path.write_text(HEAD + ZOO + board.format("kept") + board.format("restarted") + "restart = true\n")
    pipeline = load_pipeline(path, workdir=tmp_path / "w")
    run_pipeline(pipeline, progress=False)
    for name in ("kept", "restarted"):
        (tmp_path / "w" / name / "stray.txt").write_text("left by an earlier run")
    (tmp_path / "w" / "zoo" / "extra.txt").write_text("the folder it reads changed")
    assert [r.status for r in run_pipeline(pipeline, progress=False)] == ["skipped", "done", "done"]
    assert (tmp_path / "w" / "kept" / "stray.txt").exists() and not (tmp_path / "w" / "restarted" / "stray.txt").exists()
    assert (tmp_path / "w" / "restarted" / "leaderboard.json").exists()
