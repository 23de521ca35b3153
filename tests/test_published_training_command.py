"""The training commands of the published baselines' page (docs/methods/published.md) parse, train every shipped checkpoint,
and carry the settings each shipped checkpoint was trained with (its safetensors header holds the
model, stage, config, seed, epochs and the dataset's name)."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

from mimicbench.training.checkpoint import read_header

README = Path(__file__).resolve().parents[1] / "docs" / "methods" / "published.md"
SHIPPED = ("npt", "cgt", "sfpt")


def readme_training_block() -> list[list[str]]:
    text = README.read_text()
    section = text[text.index("## Training and the shipped checkpoints"):]
    block = re.search(r"```\n(.*?)```", section, re.S).group(1)
    return [shlex.split(line) for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def test_readme_training_commands_parse_and_match_the_shipped_checkpoints():
    from benchmark.registry import get_method
    from mimicbench.cli import build_parser
    from mimicbench.training.config_overrides import apply_overrides
    from mimicbench.training.registry import trainable

    parser = build_parser()
    trained = {}
    for argv in readme_training_block():
        if argv[0] != "mimicbench":
            continue
        args = parser.parse_args(argv[1:])
        if argv[1] == "train":
            trained[args.model] = (apply_overrides(trainable(args.model).config(args.config), args.overrides), args)
    assert set(trained) == set(SHIPPED)
    for name, (config, args) in trained.items():
        method = get_method(name)
        header = read_header(method.shipped / f"{name}.safetensors")
        assert header["model"] == name and header["stage"] == name and header["seed"] == args.seed
        assert header["config"] == config, name
        assert header["epoch"] == config["epochs"] and header["dataset"]["name"] == Path(args.dataset).name
