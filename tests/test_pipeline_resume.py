"""``mimicbench pipeline``: steps skipped by fingerprint, a killed pipeline resumed, bad files refused."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mimicbench.cli import main
from mimicbench.pipeline import load_pipeline, step_argv

REPO = Path(__file__).resolve().parents[1]

SMALL = """
[pipeline]
name = "small"
workdir = "unused"

[[steps]]
run = "zoo"
out = "zoo"
characters = 7
clips_per_character = 1
frames_per_clip = 12
no_contact_sheet = true
quiet = true

[[steps]]
run = "resample"
in = "zoo"
out = "zoo1k"
faces = {faces}
quiet = true

[[steps]]
run = "correspond"
dataset = "zoo1k"
pairs = 10
quiet = true
"""


def write_pipeline(tmp_path: Path, faces: int = 1000) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL.replace("{faces}", str(faces)))
    return path


def summary_statuses(text: str) -> dict:
    """step name -> status, read from the summary lines ("  zoo  done  3.1 s")."""
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] in ("zoo", "resample", "correspond") and parts[1] in (
                "done", "skipped", "partial", "failed", "not"):
            out[parts[0]] = parts[1]
    return out


def mtimes(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


def test_steps_are_skipped_until_their_inputs_or_options_change(tmp_path, capsys):
    work = tmp_path / "work"
    toml = write_pipeline(tmp_path)
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    assert summary_statuses(capsys.readouterr().out) == {"zoo": "done", "resample": "done", "correspond": "done"}
    before = mtimes(work / "zoo1k")
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet", "--engine", "ray"]) == 0
    assert summary_statuses(capsys.readouterr().out) == {"zoo": "skipped", "resample": "skipped",
                                                         "correspond": "skipped"}  # the engine is not an input
    assert mtimes(work / "zoo1k") == before
    # another face count: resample runs again, and correspond because its input changed; the zoo does not
    toml = write_pipeline(tmp_path, faces=800)
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    assert summary_statuses(capsys.readouterr().out) == {"zoo": "skipped", "resample": "done", "correspond": "done"}
    # an output deleted behind the pipeline's back is made again
    import shutil

    shutil.rmtree(work / "zoo")
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet", "--dry-run"]) == 0
    assert capsys.readouterr().out.splitlines()[0].startswith("run ")
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    out = summary_statuses(capsys.readouterr().out)
    assert out["zoo"] == "done" and out["resample"] == "skipped"  # the same zoo again: same bytes, same input


def test_a_finished_step_runs_again_when_its_code_version_changes(tmp_path, capsys, monkeypatch):
    """A new resample version (a toolkit upgrade) makes the pipeline run resample again, not skip it
    on the old output; the zoo, whose code did not change, stays skipped."""
    import mimicbench.datagen.resample

    work = tmp_path / "work"
    toml = write_pipeline(tmp_path)
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    capsys.readouterr()
    monkeypatch.setattr(mimicbench.datagen.resample, "RESAMPLE_VERSION", mimicbench.datagen.resample.RESAMPLE_VERSION + "-next")
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    out = summary_statuses(capsys.readouterr().out)
    assert out["zoo"] == "skipped" and out["resample"] == "done"
    monkeypatch.undo()
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet", "--dry-run"]) == 0
    zoo, resample, _ = capsys.readouterr().out.splitlines()
    assert zoo.startswith("skip  mimicbench zoo") and resample.startswith("run   mimicbench datagen resample")


def test_a_bench_steps_fingerprint_holds_its_methods_versions(tmp_path, monkeypatch):
    from dataclasses import replace

    from mimicbench.baselines.identity import Identity
    from mimicbench.pipeline.spec import Step
    from mimicbench.pipeline.state import code_versions

    step = Step("bench", "bench", {"dataset": "d", "methods": "identity,no_such_method", "out": "r"})
    versions = code_versions(step)
    assert versions["method:identity"] == Identity.metadata.version
    assert versions["method:no_such_method"] == "unknown"
    assert versions["toolkit"]
    monkeypatch.setattr(Identity, "metadata", replace(Identity.metadata, version="next"))
    assert code_versions(step)["method:identity"] == "next"


def test_a_cases_steps_fingerprint_holds_the_apparel_cases_version(monkeypatch):
    """New apparel case rows (cases version 2: the burn-in frames) make a finished cases step run again."""
    import mimicbench.benchmark.protocols.apparel as apparel
    from mimicbench.pipeline.spec import Step
    from mimicbench.pipeline.state import code_versions

    step = Step("cases", "cases", {"dataset": "d"})
    assert code_versions(step)["mimicbench.benchmark.protocols.apparel:CASES_VERSION"] == "2"
    monkeypatch.setattr(apparel, "CASES_VERSION", 3)
    assert code_versions(step)["mimicbench.benchmark.protocols.apparel:CASES_VERSION"] == "3"


def test_a_killed_pipeline_resumes_without_redoing_finished_steps(tmp_path, capsys):
    work = tmp_path / "work"
    toml = write_pipeline(tmp_path)
    state = work / ".pipeline" / "small.json"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "mimicbench", "pipeline", str(toml), "--workdir", str(work),
                             "--quiet"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if state.is_file() and "zoo" in json.loads(state.read_text())["steps"]:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the pipeline ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)  # the driver dies mid-run
    proc.wait()
    finished = set(json.loads(state.read_text())["steps"])
    assert "zoo" in finished and "correspond" not in finished
    zoo_files = mtimes(work / "zoo")
    assert main(["pipeline", str(toml), "--workdir", str(work), "--quiet"]) == 0
    statuses = summary_statuses(capsys.readouterr().out)
    assert statuses == {s: ("skipped" if s in finished else "done") for s in ("zoo", "resample", "correspond")}
    assert mtimes(work / "zoo") == zoo_files  # nothing of the finished step was redone
    from mimicbench.schemas.validate import validate_dataset

    assert validate_dataset(work / "zoo1k") == []


def test_step_options_become_the_command_line(tmp_path):
    p = load_pipeline(write_pipeline(tmp_path), workdir=tmp_path / "w")
    assert step_argv(p.steps[1], p) == ["datagen", "resample", str(tmp_path / "w" / "zoo"), str(tmp_path / "w" / "zoo1k"),
                                        "--faces", "1000", "--quiet", "--engine", "local"]
    p.engine, p.jobs = "ray", 2
    assert step_argv(p.steps[0], p)[-4:] == ["--engine", "ray", "--jobs", "2"]


@pytest.mark.parametrize("text, message", [
    ("[[steps]]\nrun = 'bake'\n", "run = 'bake'; expected one of"),
    ("[[steps]]\nrun = 'resample'\nin = 'a'\n", "missing out"),
    ("[[steps]]\nrun = 'zoo'\nout = 'a'\nengine = 'ray'\n", "belongs in [pipeline]"),
    ("[pipeline]\nengine = 'spark'\n[[steps]]\nrun = 'zoo'\nout = 'a'\n", "expected \"local\" or \"ray\""),
    ("[[steps]\n", "not a TOML file"),
    ("[pipeline]\nname = 'x'\n", "at least one [[steps]]"),
])
def test_bad_pipeline_files_are_refused_with_the_reason(tmp_path, capsys, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["pipeline", str(path), "--workdir", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert message in err and "bad.toml" in err
    assert not (tmp_path / "w").exists()


def test_a_pipeline_retargets_motion_capture_onto_a_character(tmp_path, assets_dir, capsys):
    # the retarget step takes two folders of earlier steps (the clips' dataset and the characters'),
    # as `datagen retarget MOTIONS CHARACTERS OUT` does, and is skipped once done; the clip keeps
    # every frame of the BVH file (its "Frames:" line, read here as text)
    from mimicbench.schemas.shards import read_records

    bvh = assets_dir / "bvh" / "CMU_02_01.bvh"
    path = tmp_path / "rt.toml"
    path.write_text(f"""
[pipeline]
name = "rt"
workdir = "w"

[[steps]]
name = "mocap"
run = "ingest"
paths = ["{bvh}"]
out = "mocap"
allow_outside = true

[[steps]]
name = "people"
run = "ingest"
paths = ["{assets_dir / 'glb' / 'Quaternius_Punk.glb'}"]
out = "people"
allow_outside = true

[[steps]]
run = "retarget"
motions = "mocap"
characters = "people"
out = "moved"
quiet = true
""")
    assert main(["pipeline", str(path), "--workdir", str(tmp_path / "w")]) == 0
    [clip] = read_records(tmp_path / "w" / "moved", "motions")
    frames = int(next(line for line in bvh.read_text().splitlines() if line.startswith("Frames:")).split()[1])
    assert len(clip.transforms) == frames
    [person] = read_records(tmp_path / "w" / "people", "characters")
    assert clip.character_id == person.character_id and clip.motion_id.startswith(person.character_id + "/")
    capsys.readouterr()
    assert main(["pipeline", str(path), "--workdir", str(tmp_path / "w")]) == 0
    lines = {line.split()[0]: line.split()[1] for line in capsys.readouterr().out.splitlines()
             if line.startswith("  ") and len(line.split()) > 1}
    assert (lines["mocap"], lines["people"], lines["retarget"]) == ("skipped",) * 3


@pytest.mark.parametrize("name", sorted(p.name for p in (REPO / "examples" / "pipelines").glob("*.toml")))
def test_the_example_pipeline_files_load(name, tmp_path):
    # every option of every step is checked when a file is loaded (nothing runs)
    pipeline = load_pipeline(REPO / "examples" / "pipelines" / name, workdir=tmp_path / "w")
    assert pipeline.steps and all(step_argv(step, pipeline) for step in pipeline.steps)
