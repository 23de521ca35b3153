"""The documentation site builds with `mkdocs build --strict` and no warning; a broken link fails it."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def build(root: Path, site: Path) -> subprocess.CompletedProcess:
    """`mkdocs build --strict` of the project at ``root`` into ``site`` (stdout and stderr together)."""
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
                           str(root / "mkdocs.yml"), "--site-dir", str(site)],
                          cwd=root, env=env, capture_output=True, text=True, timeout=600)


def warnings_of(proc: subprocess.CompletedProcess) -> list[str]:
    """mkdocs's WARNING and ERROR log lines."""
    return [line for line in (proc.stdout + proc.stderr).splitlines() if re.match(r"\s*(WARNING|ERROR)\b", line)]


def test_the_site_builds_strict_with_no_warning(tmp_path):
    proc = build(ROOT, tmp_path / "site")
    assert proc.returncode == 0 and not warnings_of(proc), proc.stdout + proc.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    formats = (tmp_path / "site" / "formats" / "index.html").read_text()
    assert "mimicbench data format" in formats  # schemas/FORMAT.md is included, not linked


def test_a_broken_link_fails_the_strict_build(tmp_path):
    """The check itself: a copy of the site with one link to a page that does not exist."""
    copy = tmp_path / "project"
    shutil.copytree(ROOT / "docs", copy / "docs")
    shutil.copy(ROOT / "mkdocs.yml", copy / "mkdocs.yml")
    (copy / "schemas").mkdir()
    shutil.copy(ROOT / "schemas" / "FORMAT.md", copy / "schemas" / "FORMAT.md")
    index = copy / "docs" / "index.md"
    index.write_text(index.read_text() + "\nSee [the missing page](no-such-page.md).\n")
    proc = build(copy, tmp_path / "site")
    assert proc.returncode != 0
    assert any("no-such-page.md" in w for w in warnings_of(proc)), proc.stdout + proc.stderr


HISTORY_IN_COMMENT = re.compile(r"\bround [0-9]|\bversions? [0-9]+|\bsince version|\bup to version|\bshipped v[0-9]", re.I)
HISTORY_IN_DOCSTRING = re.compile(r"\bround [0-9]|\b(?:methods|simulation|resample|cases|file physics|zoo) versions? [0-9]"
                                  r"|\bsince (?:methods )?version|\bup to (?:methods )?version", re.I)
VERSION_CONSTANT = re.compile(r"^[A-Z_]*VERSION\s*=")
PACKAGES = ("mimicbench", "datagen", "benchmark", "baselines", "schemas")


def history_in_source(source: str) -> list[str]:
    """Lines of Python ``source`` whose comments or docstrings tell history ("round 3", "methods
    version 6", "since version 8"), and version constants whose comment runs past one line (the
    versions' history belongs in CHANGELOG.md)."""
    import io
    import tokenize

    found = []
    tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    lines = source.splitlines()
    for tok in tokens:
        if tok.type == tokenize.COMMENT and HISTORY_IN_COMMENT.search(tok.string):
            found.append(f"{tok.start[0]}: {tok.string}")
        elif tok.type == tokenize.STRING and tok.string.lstrip("rbuRBU").startswith(('"""', "'''")):
            for i, line in enumerate(tok.string.splitlines()):
                if HISTORY_IN_DOCSTRING.search(line):
                    found.append(f"{tok.start[0] + i}: {line.strip()}")
    for n, line in enumerate(lines):
        if VERSION_CONSTANT.match(line) and "#" in line and n + 1 < len(lines) and lines[n + 1].lstrip().startswith("#"):
            found.append(f"{n + 1}: {line.strip()} (a comment of several lines on a version constant)")
    return found


def test_history_finder_on_hand_written_sources():
    """The finder itself: what it flags and what it lets through."""
    flagged = history_in_source('X = 1  # round 3 made this 1\n'
                                'def f():\n    """Trained as in methods version 6."""\n'
                                'SIM_VERSION = "2"  # 2: gravity\n# 3: capsules\n'
                                'y = 2  # shipped v9: 0.03\n')
    assert [f.split(":")[0] for f in flagged] == ["1", "3", "6", "4"]
    clean = history_in_source('SIM_VERSION = "14"  # recorded in each clip; CHANGELOG.md says what changed\n'
                              '"""Read PMD files (the format, version 1.0): the shipped checkpoint."""\n'
                              'z = 3  # the shipped weights\n')
    assert clean == []


def test_no_history_in_code_comments():
    found = [f"{path}:{hit}" for pkg in PACKAGES for path in sorted((ROOT / pkg).rglob("*.py"))
             for hit in history_in_source(path.read_text())]
    assert not found, "history belongs in CHANGELOG.md or docs/notes/, not in code comments:\n" + "\n".join(found)
