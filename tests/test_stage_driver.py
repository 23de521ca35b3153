"""The stage driver (datagen/stage_runner.py ``drive``): one loop for every datagen stage.

Checked against independent facts: the manifest as the format spec defines it (``complete``,
``pending``) read at the moment each Parquet file is written, shard bytes of an uninterrupted run,
the parser's own actions compared with the dataclass fields, and the files a test writes itself.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from mimicbench.datagen.stage_runner import Stage, StagePlan, drive, not_a_param
from mimicbench.datagen.stages import STAGES
from mimicbench.runtime.options import option, option_fields, options_class, toml_keys
from mimicbench.schemas.manifest import MANIFEST
from mimicbench.schemas.shards import read_records

NOT_ON_THE_COMMAND_LINE = {"ingest": {"assets_per_process"}, "correspond": {"block"}, "apparel": {"batch"}}


@dataclass(frozen=True)
class ToyParams:
    out: str = not_a_param(None, folder=True)
    size: int = option(2)
    quiet: bool = not_a_param(True)


def _toy_item(item: int, size: int) -> int:
    if item == 2:
        raise ValueError("item 2 is bad")
    return item * size


class ToyPlan(StagePlan):
    def __init__(self, run):
        super().__init__(run.stage, range(5))
        self.kwargs = {"size": run.params.size}
        self.results = {}

    def name_of(self, item) -> str:
        return f"item-{item}"

    def done(self, run, item, ok, result) -> None:
        if ok:
            self.results[item] = result


TOY = Stage("toy", ToyParams, inputs=(), item=_toy_item, outputs=("status",), made_by="status", plan=ToyPlan)


def test_an_item_that_raises_is_a_failed_status_row_and_the_others_go_on(tmp_path):
    s = drive(TOY, ToyParams(str(tmp_path / "out")))
    rows = {r.asset: r for r in read_records(tmp_path / "out", "status")}
    assert sorted(rows) == [f"item-{i}" for i in range(5)]
    assert rows["item-2"].status == "failed" and "ValueError: item 2 is bad" in rows["item-2"].reason
    assert all(rows[f"item-{i}"].status == "ok" for i in (0, 1, 3, 4))
    assert (s.ok, s.failed, s.exit_code) == (4, 1, 1)
    manifest = json.loads((tmp_path / "out" / MANIFEST).read_text())
    assert manifest["complete"] is True and "pending" not in manifest


def _watch_writes(monkeypatch, out: Path, stage: str) -> list[Path]:
    """Record every Parquet file written under ``out``; fail when the manifest does not say, at that
    moment, that ``stage`` is writing ``out`` (``complete: false``, ``pending.stage``)."""
    written = []
    real = pq.write_table

    def checked(table, where, *args, **kwargs):
        path = Path(where)
        if path.resolve().is_relative_to(out.resolve()):
            manifest_path = out / MANIFEST
            assert manifest_path.is_file(), f"{path} written before {out} was marked incomplete"
            manifest = json.loads(manifest_path.read_text())
            assert manifest["complete"] is False and manifest["pending"]["stage"] == stage, \
                f"{path} written while the manifest says {manifest.get('complete')}, {manifest.get('pending')}"
            written.append(path)
        return real(table, where, *args, **kwargs)

    monkeypatch.setattr(pq, "write_table", checked)
    return written


def test_begin_precedes_every_write_of_the_mmd_route(tmp_path, monkeypatch):
    from mimicbench.datagen.ingest.runner import ingest_assets
    from tests.mmd_fixtures import pmx_bytes

    (tmp_path / "a.pmx").write_bytes(pmx_bytes())
    out = tmp_path / "ds"
    written = _watch_writes(monkeypatch, out, "ingest")
    ingest_assets([tmp_path / "a.pmx"], out, progress=False)
    tables = {p.parent.name for p in written}
    assert {"characters", "rigid_bodies", "joints", "status"} <= tables  # the physics tables too


def test_begin_precedes_every_write_of_zoo_and_resample(tmp_path, monkeypatch):
    from mimicbench.datagen.resample.stage import resample_dataset
    from mimicbench.datagen.zoo.dataset import build_zoo

    zoo = tmp_path / "zoo"
    written = _watch_writes(monkeypatch, zoo, "zoo")
    build_zoo(zoo, 2, seed=3, clips_per_character=1, frames_per_clip=12, progress=False)
    assert {p.parent.name for p in written} == {"characters", "motions", "status"}
    out = tmp_path / "rs"
    written = _watch_writes(monkeypatch, out, "resample")
    resample_dataset(zoo, out, faces=300, progress=False, flush_every=1)
    assert {p.parent.name for p in written} >= {"characters", "status"}


def _digests(root: Path, table: str) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((root / table).glob("*.parquet"))}


@pytest.mark.slow
def test_an_interrupted_run_resumes_and_ends_with_the_bytes_of_an_uninterrupted_one(small_zoo, tmp_path, monkeypatch):
    from mimicbench.datagen.resample import stage

    clean, out = tmp_path / "clean", tmp_path / "out"
    stage.resample_dataset(small_zoo, clean, faces=300, progress=False)
    real, calls = stage.resample_character, []

    def interrupted(record, *args, **kwargs):
        calls.append(record.character_id)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(record, *args, **kwargs)

    monkeypatch.setattr(stage, "resample_character", interrupted)
    with pytest.raises(KeyboardInterrupt):
        stage.resample_dataset(small_zoo, out, faces=300, progress=False, flush_every=1)
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["complete"] is False and manifest["pending"]["stage"] == "resample"
    monkeypatch.setattr(stage, "resample_character", real)
    again = stage.resample_dataset(small_zoo, out, faces=300, progress=False)
    assert again["already_done"] == 3 and again["failed"] == 0  # the three finished before the interrupt
    assert _digests(out, "characters") == _digests(clean, "characters")
    assert json.loads((out / MANIFEST).read_text())["complete"] is True


def _command_parser(words: tuple[str, ...]) -> argparse.ArgumentParser:
    from mimicbench.cli import build_parser

    parser = build_parser()
    for word in words:
        parser = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[word]
    return parser


@pytest.mark.parametrize("name", sorted(STAGES.names()))
def test_the_command_line_options_are_the_params_fields(name):
    stage = STAGES.get(name)
    parser = _command_parser(stage.command)
    assert options_class(parser) is stage.params
    dests = {a.dest: a for a in parser._actions
             if not isinstance(a, argparse._HelpAction) and a.default is not argparse.SUPPRESS}
    fields = {f.name: f for f in dataclasses.fields(stage.params)}
    assert set(dests) == set(fields) - NOT_ON_THE_COMMAND_LINE.get(name, set())
    for dest, action in dests.items():  # declared once: each option's help is its field's
        assert (action.help or "") == fields[dest].metadata.get("help", ""), dest


@pytest.mark.parametrize("name", sorted(STAGES.names()))
def test_the_pipeline_keys_of_a_stage_are_its_fields(name, tmp_path):
    from mimicbench.pipeline.spec import STEP_KINDS, load_pipeline

    stage = STAGES.get(name)
    kind = STEP_KINDS[name]
    assert kind.params is stage.params and kind.command == stage.command
    keys = toml_keys(stage.params)
    assert sorted(keys.values()) == sorted(f.name for f in option_fields(stage.params))
    needed = {k: "x" for k in kind.needs}
    extra = "[[steps]]\nrun = '%s'\n" % name + "".join(f"{k} = 'x'\n" for k in needed) + "not_a_field = 1\n"
    path = tmp_path / "p.toml"
    path.write_text("[pipeline]\nname = 'p'\n" + extra)
    with pytest.raises(ValueError, match="unknown option 'not_a_field'"):
        load_pipeline(path, workdir=tmp_path / "w")


def test_the_pipeline_builds_no_command_line(tmp_path):
    """Loading and checking a pipeline file imports neither mimicbench.cli nor argparse's whole tree."""
    src = Path(__file__).resolve().parents[1] / "examples" / "pipelines" / "demo.toml"
    code = ("import sys; from mimicbench.pipeline import load_pipeline, step_options; "
            f"p = load_pipeline({str(src)!r}, workdir={str(tmp_path)!r}); "
            "[step_options(s, p) for s in p.steps]; "
            "assert 'mimicbench.cli' not in sys.modules, 'the pipeline imported mimicbench.cli'")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).resolve().parents[1])


def test_ingest_formats_are_one_loader_table():
    from mimicbench.datagen.ingest.asset_paths import FOLDER_SUFFIXES
    from mimicbench.datagen.ingest.loaders import LOADERS, loader_for

    assert {s for s, loader in LOADERS.items() if loader.in_blender} == {".glb", ".gltf", ".fbx", ".bvh", ".obj",
                                                                          ".blend"}
    assert loader_for("A.GLB").name == "blender" and loader_for("m.pmx").name == "mmd model"
    assert loader_for("m.pmd").function().__name__ == "load_model"
    assert loader_for("m.vmd").task is None and ".vmd" not in FOLDER_SUFFIXES  # read by the model it plays on
    assert loader_for("notes.txt") is None
    assert set(FOLDER_SUFFIXES) == set(LOADERS) - {".vmd"}


def test_a_run_that_changes_nothing_writes_nothing(small_zoo, tmp_path):
    """The roles stage with its labels already attached: the driver never marks the folder incomplete."""
    from mimicbench.datagen.roles.attach import attach_roles
    from mimicbench.schemas.shards import write_records

    hum = next(c for c in read_records(small_zoo, "characters") if c.character_id == "zoo/humanoid-0000")
    root = tmp_path / "data"
    write_records(root, "characters", [dataclasses.replace(hum, character_id="assets/Biped", source="/a/Biped.glb",
                                                           bone_roles=None, split="train")], "train")
    labels = tmp_path / "l.toml"
    labels.write_text('[characters."assets/Biped".bones]\n'
                      + "".join(f'"{n}" = "{r}"\n' for n, r in zip(hum.bone_names, hum.bone_roles) if r))
    assert attach_roles(root, [labels])["written_splits"] == ["train"]
    before = (root / MANIFEST).read_bytes(), (root / MANIFEST).stat().st_mtime_ns
    s = attach_roles(root, [labels])
    assert s["written_splits"] == [] and s["labelled"]["assets/Biped"]["labelled"] > 0
    assert ((root / MANIFEST).read_bytes(), (root / MANIFEST).stat().st_mtime_ns) == before
