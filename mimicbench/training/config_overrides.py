"""``--set key=value`` overrides of a model config: dotted keys into nested dicts, JSON values."""
from __future__ import annotations

import json

from mimicbench.schemas.errors import UserError


def _leaf_keys(config: dict, prefix: str = "") -> list[str]:
    keys = []
    for k, v in config.items():
        keys += _leaf_keys(v, f"{prefix}{k}.") if isinstance(v, dict) else [f"{prefix}{k}"]
    return keys


def parse_value(text: str):
    """``"3"`` -> 3, ``"1e-4"`` -> 0.0001, ``"true"`` -> True, ``"[1,2]"`` -> [1, 2], else the string."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def apply_overrides(config: dict, items: list[str]) -> dict:
    """Apply ``["a.b=1", "lr=3e-4"]`` to ``config`` in place and return it.

    Keys must already exist in the config (a typo fails with the list of known keys), except
    ``lr``, ``weight_decay``, ``grad_clip`` and ``epochs``, which the loop reads at the top level
    or under a stage (``shape.lr=3e-4``).
    """
    loop_keys = {"lr", "weight_decay", "grad_clip", "epochs", "find_unused_parameters"}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise UserError(f"--set expects key=value (e.g. shape.width=64 or lr=3e-4), got {item!r}")
        parts = key.split(".")
        node = config
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                raise UserError(f"--set {item!r}: {p!r} is not a section of the config; known keys: "
                                f"{', '.join(_leaf_keys(config))}")
            node = node[p]
        if parts[-1] not in node and parts[-1] not in loop_keys:
            raise UserError(f"--set {item!r}: unknown key {key!r}; known keys: {', '.join(_leaf_keys(config))}")
        node[parts[-1]] = parse_value(text)
    return config
