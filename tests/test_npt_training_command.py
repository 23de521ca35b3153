"""The documented training commands of the published baselines (docs/methods/published-deviations.md)
parse, give the config and seed each shipped checkpoint's header holds, and (slow) build the datasets
they train on with the table fingerprints each header recorded: a change to the zoo or the resampling that makes the
documented commands build other meshes than the shipped weights saw fails here."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from mimicbench.training.checkpoint import read_header

DOC = Path(__file__).resolve().parents[1] / "docs" / "methods" / "published-deviations.md"
SHIPPED = ("npt", "cgt", "sfpt")
TRAINED_ON = ("characters", "motions")


def doc_commands() -> list[list[str]]:
    """argv lists of the ``bash`` block of the page's section ``## Training the shipped checkpoints``."""
    text = DOC.read_text()
    section = text[text.index("## Training the shipped checkpoints"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [shlex.split(line) for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def shipped_header(name: str) -> dict:
    from mimicbench.benchmark.registry import get_method

    return read_header(get_method(name).shipped / f"{name}.safetensors")


def test_documented_commands_parse_and_match_the_shipped_headers():
    from mimicbench.cli import build_parser
    from mimicbench.training.config_overrides import apply_overrides
    from mimicbench.training.loop import stage_setting
    from mimicbench.training.registry import trainable

    parser = build_parser()
    trained = {}
    for argv in doc_commands():
        if argv[0] != "mimicbench":
            continue
        args = parser.parse_args(argv[1:])
        if argv[1] == "train":
            trained[args.model] = (apply_overrides(trainable(args.model).config(args.config), args.overrides), args)
    assert set(trained) == set(SHIPPED)
    for name, (config, args) in trained.items():
        header = shipped_header(name)
        last = trainable(name).stages[-1].name  # the stage whose weights ship (sfpt: its decoder stage)
        assert header["model"] == name and header["stage"] == last and header["seed"] == args.seed
        assert header["config"] == config, name
        epochs = args.epochs if args.epochs is not None else stage_setting(config, last, "epochs", 1)  # --epochs: every stage
        assert header["epoch"] == epochs and header["dataset"]["name"] == Path(args.dataset).name
        assert header["dataset"].get("tables"), f"{name}: the header records no dataset fingerprint"


@pytest.mark.slow
def test_documented_commands_build_the_dataset_the_shipped_weights_saw(tmp_path):
    from mimicbench.cli import main
    from mimicbench.training.checkpoint import dataset_provenance

    trains_on = {}  # model -> the dataset folder its documented `train` command reads
    for argv in doc_commands():
        if argv[0] != "mimicbench":
            continue
        argv = [a.replace("data/", f"{tmp_path}/") for a in argv[1:]]
        if argv[0] == "train":
            trains_on[argv[1]] = argv[2]
            continue
        assert main(argv) in (0, None), argv
    assert set(trains_on) == set(SHIPPED)
    for name in SHIPPED:
        tables = dataset_provenance(trains_on[name])["tables"]
        recorded = shipped_header(name)["dataset"]["tables"]
        for table in TRAINED_ON:  # the tables the trainers read (``status`` holds run times, not data)
            assert recorded[table] == tables[table], (
                f"{name}: the documented commands build another {table} table than the shipped weights trained on")
