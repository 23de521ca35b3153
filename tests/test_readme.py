"""README.md is a short front door whose commands are real and whose plug-in example runs as written."""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.bench_fixtures import make_bench_dataset

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 250


def readme_commands(text: str) -> list[str]:
    """What follows `mimicbench ` on each shell line of a non-Python code block, and in each inline
    code span that starts with `mimicbench `."""
    blocks = re.findall(r"```(?!python)\w*\n(.*?)```", text, re.S)
    lines = [m for b in blocks for m in re.findall(r"^mimicbench (.+?)(?:\s{2,}#|$)", b, re.M)]
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    spans = re.findall(r"`mimicbench ([^`]+)`", prose)
    return lines + spans


def command_path(parser: argparse.ArgumentParser, words: list[str]) -> list[str]:
    """The leading words of ``words`` that name subcommands, walking the parser's subcommand tree."""
    path = []
    for word in words:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs or word not in subs[0].choices:
            break
        path.append(word)
        parser = subs[0].choices[word]
    return path


def test_readme_is_at_most_250_lines():
    n = len(README.read_text().splitlines())
    assert n <= MAX_LINES, f"README.md has {n} lines; at most {MAX_LINES} (the rest belongs in docs/)"


def test_command_path_walks_the_tree():
    """The walker itself, on a parser built here."""
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    bench = sub.add_parser("bench").add_subparsers()
    bench.add_parser("run")
    sub.add_parser("zoo")
    assert command_path(parser, ["bench", "run", "DATA", "--out", "x"]) == ["bench", "run"]
    assert command_path(parser, ["zoo", "--out", "data/zoo"]) == ["zoo"]
    assert command_path(parser, ["bnech", "run"]) == []


def test_every_command_the_readme_names_parses():
    from mimicbench.cli import build_parser

    parser = build_parser()
    commands = readme_commands(README.read_text())
    assert len(commands) >= 10, commands
    for command in commands:
        words = command.split()
        if words[0].startswith("-") or words[0].isupper():  # `mimicbench --help`, `mimicbench COMMAND --help`
            continue
        path = command_path(parser, words)
        assert path, f"README names `mimicbench {command}`, whose first word is no mimicbench command"
        with pytest.raises(SystemExit) as exc:
            parser.parse_args(path + ["--help"])
        assert exc.value.code == 0, command


def test_readme_plugin_example_runs_as_a_script(small_zoo, tmp_path):
    """The README's Python block, saved as a file and run as `python my_method.py DATASET RESULTS` in a
    fresh interpreter: its own method runs in process, `name_copy` in a worker process, and both score
    every case (no worker died, nothing failed)."""
    from mimicbench.benchmark.aggregate import aggregate

    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    script = tmp_path / "my_method.py"
    script.write_text(code)
    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=2, cct_pairs=2, cct_poses=1)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, script.name, str(data), str(tmp_path / "res")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    log = proc.stdout + proc.stderr
    assert "worker died" not in log
    assert "method 'name_copy': class" not in log  # name_copy ran in its worker process, not in process
    entries = aggregate(tmp_path / "res")["protocols"]
    assert set(entries) == {"h2h", "cct"}
    for protocol, rows in entries.items():
        assert {r["method"] for r in rows} == {"my_method", "name_copy"}, protocol
        assert all(r["complete"] and r["failed"] == 0 and r["ok"] == r["cases"] > 0 for r in rows), rows
