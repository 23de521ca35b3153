"""Every shipped MimiCAT checkpoint carries the documented config: the ``small`` preset of
``baselines/mimicat/config.py`` with the stage's training-budget overrides (``SHIPPED_OVERRIDES``),
every setting the method reads written out, so the method never falls back to a default that a
config without the key means."""
from __future__ import annotations

import pytest

from mimicbench.baselines.mimicat.config import (BUDGET_KEYS, SHIPPED_OVERRIDES, SHIPPED_STAGES, STAGE_SECTIONS, preset,
                                      shipped_config)
from mimicbench.baselines.mimicat.method import BUNDLED
from mimicbench.training.checkpoint import read_header

LOOP_KEYS = ("lr", "weight_decay", "grad_clip")


def config_differences(stored: dict, documented: dict, sections) -> list[str]:
    """``section.key: stored != documented`` for every key of the loop's top level and of
    ``sections`` that differs, is missing on one side, or is extra on the other."""
    out = [f"{k}: {stored.get(k)!r} != {documented.get(k)!r}" for k in LOOP_KEYS if stored.get(k) != documented.get(k)]
    for sec in sections:
        a, b = stored.get(sec) or {}, documented.get(sec) or {}
        out += [f"{sec}.{k}: {a.get(k, '<missing>')!r} != {b.get(k, '<missing>')!r}"
                for k in sorted(a.keys() | b.keys()) if a.get(k, "<missing>") != b.get(k, "<missing>")]
    return out


def test_config_differences_by_hand():
    documented = {"lr": 1.0, "transfer": {"init": "structured", "m_decode": "hungarian_sym", "width": 64}}
    assert config_differences(documented, documented, ("transfer",)) == []
    stored = {"lr": 1.0, "transfer": {"width": 64, "extra": 1}}
    assert config_differences(stored, documented, ("transfer",)) == [
        "transfer.extra: 1 != '<missing>'", "transfer.init: '<missing>' != 'structured'",
        "transfer.m_decode: '<missing>' != 'hungarian_sym'"]
    assert config_differences({"lr": 2.0}, {"lr": 1.0}, ()) == ["lr: 2.0 != 1.0"]


def test_shipped_overrides_touch_only_the_training_budget_and_change_something():
    assert set(SHIPPED_OVERRIDES) == set(SHIPPED_STAGES) == set(STAGE_SECTIONS)
    small = preset("small")
    for stage, overrides in SHIPPED_OVERRIDES.items():
        assert set(overrides) <= set(BUDGET_KEYS), stage
        for key, value in overrides.items():
            section, _, name = key.rpartition(".")
            assert small[section][name] != value, f"{stage}: {key}={value!r} is already the preset's value"
    config = shipped_config("prior")
    assert config["prior"]["epochs"] == 8 and config["prior"]["sampling_weight"] == 0
    assert config["data"]["split"] == "all" and config["transfer"] == small["transfer"]


@pytest.mark.parametrize("stage", SHIPPED_STAGES)
def test_shipped_checkpoint_config_is_the_documented_config(stage):
    header = read_header(BUNDLED / f"{stage}.safetensors")
    documented = shipped_config(stage)
    assert header["stage"] == stage and header["model"] == "mimicat"
    diffs = config_differences(header["config"], documented, STAGE_SECTIONS[stage])
    assert diffs == [], f"{stage}.safetensors differs from config.shipped_config({stage!r}): {diffs}"
    own = documented[stage].get("epochs")
    assert header["epoch"] == own, f"{stage}: trained {header['epoch']} epochs, its config says {own}"


def test_the_shipped_method_reads_the_structured_pipeline_from_its_checkpoint():
    """``mimicat`` reads ``init``, ``m_decode``, ``m_temperature`` and ``points`` from the transfer
    checkpoint; with the documented config that is the presets' structured pipeline."""
    from mimicbench.baselines.mimicat.method import Mimicat, MimicatNoPrior

    small = preset("small")
    for cls in (Mimicat, MimicatNoPrior):
        method = cls(arap=False)
        method.setup("cpu")
        assert method._modules["transfer"].init == small["transfer"]["init"] == "structured"
        assert method.decode == small["transfer"]["m_decode"] == "hungarian_sym"
        assert method.m_temperature == small["transfer"]["m_temperature"]
        assert method.points == small["data"]["points"]


def test_shipped_range_model_holds_the_documented_settings():
    import json

    from safetensors import safe_open

    from mimicbench.baselines.mimicat.config import SHIPPED_RANGE
    from mimicbench.baselines.mimicat.range_model import FEATURE_SCALES, RangeModel

    path = BUNDLED / "range.safetensors"
    assert path.stat().st_size <= 2 * 2**20
    with safe_open(str(path), framework="numpy") as f:
        meta = f.metadata()
    stored = {"k": int(meta["k"]), "slack_deg": float(meta["slack_deg"]), "parts": meta["parts"], "keep": meta["keep"],
              "scope": meta["scope"], "max_deg": float(meta["max_deg"]),
              "feature_scales": json.loads(meta["feature_scales"])}
    assert stored == SHIPPED_RANGE and FEATURE_SCALES == SHIPPED_RANGE["feature_scales"]
    model = RangeModel.load(path)
    assert len(model.features) == len(model.twist) == len(model.characters) == len(model.hull_offsets) - 1
    assert model.source["characters"] == 40  # every character of the seed-11 training zoo
