"""The documented MimiCAT training commands (docs/methods/mimicat-current.md) parse, cover every
shipped stage, and give exactly the documented config of each shipped checkpoint
(``mimicbench.baselines.mimicat.config.shipped_config``), which its safetensors header holds with its seed."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

from mimicbench.baselines.mimicat.config import SHIPPED_STAGES, STAGE_SECTIONS, shipped_config
from mimicbench.baselines.mimicat.method import BUNDLED
from mimicbench.training.checkpoint import read_header

DOC = Path(__file__).resolve().parents[1] / "docs" / "methods" / "mimicat-current.md"
LOOP_KEYS = ("lr", "weight_decay", "grad_clip")


def doc_training_block() -> list[list[str]]:
    """The shell commands (argv lists, continuations joined) of the first ``bash`` fenced block of
    the page's section ``## Training the shipped checkpoint``."""
    text = DOC.read_text()
    section = text[text.index("## Training the shipped checkpoint"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [shlex.split(line) for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def test_documented_training_commands_parse_and_match_the_shipped_checkpoints():
    from mimicbench.cli import build_parser
    from mimicbench.training.config_overrides import apply_overrides
    from mimicbench.training.registry import trainable

    parser = build_parser()
    commands = doc_training_block()
    trained = {}
    for argv in commands:
        if argv[0] != "mimicbench":
            continue
        args = parser.parse_args(argv[1:])  # every mimicbench line parses (SystemExit otherwise)
        if argv[1] == "train":
            assert args.model == "mimicat" and args.stage in SHIPPED_STAGES, argv
            trained[args.stage] = (apply_overrides(trainable("mimicat").config(args.config), args.overrides), args)
    assert set(trained) == set(SHIPPED_STAGES), f"{DOC.name} trains {sorted(trained)}, the package ships {SHIPPED_STAGES}"
    for stage, (config, args) in trained.items():
        header = read_header(BUNDLED / f"{stage}.safetensors")
        assert header["stage"] == stage and header["seed"] == args.seed
        documented = shipped_config(stage)
        for key in STAGE_SECTIONS[stage]:
            assert header["config"].get(key) == config.get(key) == documented.get(key), (stage, key)
        for key in LOOP_KEYS:
            assert header["config"].get(key) == config.get(key) == documented.get(key), (stage, key)
    copy = [argv for argv in commands if argv[0] == "for"]
    assert copy and all(re.search(rf"\b{s}\b", " ".join(copy[0])) for s in SHIPPED_STAGES), \
        "the block ends by copying every stage into the package"
