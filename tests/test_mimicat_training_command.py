"""The README's MimiCAT training commands parse, cover every shipped stage, and carry the settings
each shipped checkpoint was trained with (its safetensors header holds the config and seed)."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

from baselines.mimicat.method import BUNDLED
from mimicbench.training.checkpoint import read_header

README = Path(__file__).resolve().parents[1] / "README.md"
SHIPPED = ("shape", "prior", "corr", "transfer", "transfer_no_prior")
LOOP_KEYS = ("lr", "weight_decay", "grad_clip")
ADDED_LATER = {"corr": {"geometry_weight": 0.0}, "transfer": {"init": "paper", "m_decode": "soft"}}
"""Settings added to the presets after a checkpoint could have been trained, with the value that
a header without them means (the code reads them with that default)."""


def readme_training_block() -> list[list[str]]:
    """The shell commands (argv lists, continuations joined) of the first fenced block of the
    README's MimiCAT section."""
    text = README.read_text()
    section = text[text.index("## The MimiCAT reference"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [shlex.split(line) for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def stage_sections(stage: str) -> tuple[str, ...]:
    """Config sections a stage reads (the data section and its own; A2 takes transfer's settings)."""
    return ("data", "shape") + {"shape": (), "prior": ("prior",), "corr": ("corr",), "transfer": ("corr", "transfer"),
                                "transfer_no_prior": ("corr", "transfer", "transfer_no_prior")}[stage]


def test_readme_training_commands_parse_and_match_the_shipped_checkpoints():
    from mimicbench.cli import build_parser
    from mimicbench.training.config_overrides import apply_overrides
    from mimicbench.training.registry import trainable

    parser = build_parser()
    commands = readme_training_block()
    trained = {}
    for argv in commands:
        if argv[0] != "mimicbench":
            continue
        args = parser.parse_args(argv[1:])  # every mimicbench line parses (SystemExit otherwise)
        if argv[1] == "train":
            assert args.model == "mimicat" and args.stage in SHIPPED, argv
            trained[args.stage] = (apply_overrides(trainable("mimicat").config(args.config), args.overrides), args)
    assert set(trained) == set(SHIPPED), f"the README trains {sorted(trained)}, the package ships {SHIPPED}"
    for stage, (config, args) in trained.items():
        header = read_header(BUNDLED / f"{stage}.safetensors")
        assert header["stage"] == stage and header["seed"] == args.seed
        for key in stage_sections(stage):
            stored = header["config"].get(key)
            if key in ADDED_LATER and stored is not None:
                stored = {**ADDED_LATER[key], **stored}
            assert stored == config.get(key), (stage, key)
        for key in LOOP_KEYS:
            assert header["config"].get(key) == config.get(key), (stage, key)
    copy = [argv for argv in commands if argv[0] == "for"]
    assert copy and all(re.search(rf"\b{s}\b", " ".join(copy[0])) for s in SHIPPED), "the block ends by copying every stage into the package"
