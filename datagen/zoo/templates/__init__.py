"""Category templates: ``TEMPLATES[category] = (params(rng, variant) -> dict, build(builder, params))``."""
from __future__ import annotations

from mimicbench.datagen.zoo.templates.apparel import apparel_params, build_apparel
from mimicbench.datagen.zoo.templates.bird import bird_params, build_bird
from mimicbench.datagen.zoo.templates.fish import build_fish, fish_params
from mimicbench.datagen.zoo.templates.humanoid import build_humanoid, humanoid_params
from mimicbench.datagen.zoo.templates.insect import build_insect, insect_params
from mimicbench.datagen.zoo.templates.quadruped import build_quadruped, quadruped_params
from mimicbench.datagen.zoo.templates.reptile import build_reptile, reptile_params

TEMPLATES = {
    "humanoid": (lambda rng, variant: humanoid_params(rng), build_humanoid),
    "quadruped": (quadruped_params, build_quadruped),
    "bird": (bird_params, build_bird),
    "fish": (fish_params, build_fish),
    "reptile": (reptile_params, build_reptile),
    "insect": (insect_params, build_insect),
    "apparel": (apparel_params, build_apparel),
}

ZOO_CATEGORIES = tuple(TEMPLATES)
