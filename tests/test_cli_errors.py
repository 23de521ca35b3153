"""CLI error format (``mimicbench: error: ...``, exit 2, --debug) and numeric option range checks."""
from __future__ import annotations

import argparse

import pytest

from mimicbench.runtime.argtypes import comma_choices, float_in, int_in, nonnegative_int, positive_float, positive_int
from mimicbench.cli import main
from mimicbench.schemas.errors import DatasetError


def test_int_and_float_types_accept_the_range_and_name_it_when_rejecting():
    assert positive_int("3") == 3 and nonnegative_int("0") == 0 and int_in(100, 200)("200") == 200
    assert positive_float("0.05") == pytest.approx(0.05) and float_in(0, 1)("1") == pytest.approx(1.0)
    cases = [(positive_int, "0", "an integer >= 1"), (positive_int, "-1", ">= 1"), (positive_int, "1.5", ">= 1"),
             (int_in(100, 200), "201", ">= 100 and <= 200"), (positive_float, "0", "> 0"),
             (positive_float, "nan", "finite"), (positive_float, "inf", "finite"),
             (float_in(0, 1, high_open=True), "1", "< 1"), (nonnegative_int, "x", ">= 0")]
    for parse, text, said in cases:
        with pytest.raises(argparse.ArgumentTypeError, match=said):
            parse(text)


def test_comma_choices_keeps_order_drops_duplicates_and_rejects_unknown_or_empty():
    parse = comma_choices(("obj", "bvh"))
    assert parse("bvh, obj,bvh") == ("bvh", "obj") and parse("") == ()
    with pytest.raises(argparse.ArgumentTypeError, match="unknown 'stl'.*obj, bvh"):
        parse("obj,stl")
    with pytest.raises(argparse.ArgumentTypeError, match="at least one"):
        comma_choices(("a",), allow_empty=False)(" , ")


@pytest.mark.parametrize("argv,said", [
    (["zoo", "--out", "X", "--characters", "0"], "argument --characters: expected an integer >= 1 and <= 100000, got '0'"),
    (["zoo", "--out", "X", "--seed", "-1"], "argument --seed: expected an integer >= 0"),
    (["zoo", "--out", "X", "--clips-per-character", "0"], "argument --clips-per-character"),
    (["zoo", "--out", "X", "--export", "stl"], "argument --export: unknown 'stl'"),
    (["datagen", "resample", "A", "B", "--faces", "0"], "argument --faces: expected an integer >= 100 and <= 1000000, got '0'"),
    (["datagen", "resample", "A", "B", "--faces", "2000000"], "argument --faces: expected an integer >= 100"),
    (["datagen", "resample", "A", "B", "--jobs", "0"], "argument --jobs: expected an integer >= 1 and <= 256"),
    (["datagen", "resample", "A", "B", "--jobs", "100000"], "argument --jobs: expected an integer >= 1 and <= 256"),
    (["datagen", "correspond", "A", "--temperature", "0"], "argument --temperature: expected a finite number > 0"),
    (["datagen", "correspond", "A", "--pairs", "-1"], "argument --pairs: expected an integer >= 1"),
    (["datagen", "correspond", "A", "--seed", "-2"], "argument --seed: expected an integer >= 0"),
])
def test_out_of_range_options_are_errors_that_say_what_is_allowed(argv, said, tmp_path, capsys):
    argv = [str(tmp_path / a) if a in ("X", "A", "B") else a for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"mimicbench: error: {said}" in err
    assert not any(tmp_path.iterdir())  # nothing was created


def test_user_errors_print_one_line_and_exit_2_and_debug_shows_the_traceback(tmp_path, capsys, monkeypatch):
    import mimicbench.commands.validate as validate_cmd

    def boom(args):
        raise DatasetError(f"{tmp_path}/manifest.json: missing")

    monkeypatch.setattr(validate_cmd, "run", boom)
    assert main(["validate", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mimicbench: error: {tmp_path}/manifest.json: missing\n") and "Traceback" not in err
    for argv in (["--debug", "validate", str(tmp_path)], ["validate", str(tmp_path), "--debug"]):
        with pytest.raises(DatasetError):
            main(argv)

    def missing(args):
        open(tmp_path / "nope.json")

    monkeypatch.setattr(validate_cmd, "run", missing)
    assert main(["validate", str(tmp_path)]) == 2
    assert f"mimicbench: error: {tmp_path}/nope.json: No such file or directory" in capsys.readouterr().err


def test_a_bug_is_not_dressed_up_as_a_user_error(tmp_path, monkeypatch):
    import mimicbench.commands.validate as validate_cmd

    monkeypatch.setattr(validate_cmd, "run", lambda args: [][1])
    with pytest.raises(IndexError):
        main(["validate", str(tmp_path)])


def test_no_verify_flag_sets_the_environment_for_workers(tmp_path, monkeypatch):
    import mimicbench.commands.validate as validate_cmd

    seen = {}
    monkeypatch.setenv("MIMICBENCH_VERIFY", "1")  # restored after the test
    monkeypatch.setattr(validate_cmd, "run", lambda args: seen.setdefault("v", __import__("os").environ.get("MIMICBENCH_VERIFY")) and 0)
    main(["validate", str(tmp_path), "--no-verify"])
    assert seen["v"] == "0"
