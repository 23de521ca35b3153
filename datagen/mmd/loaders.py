"""The MMD formats' ingest loaders (merged into :data:`mimicbench.datagen.ingest.loaders.LOADERS`):
a model is one item, read here without Blender; a motion is read by the models it plays on."""
from __future__ import annotations

from mimicbench.datagen.ingest.loader import Loader
from mimicbench.datagen.mmd import MODEL_SUFFIXES, MOTION_SUFFIXES

MMD_MODEL = Loader("mmd model", "mimicbench.datagen.mmd.ingest:load_model")
MMD_MOTION = Loader("mmd motion", None, walked=False)
MMD_LOADERS = {**{s: MMD_MODEL for s in MODEL_SUFFIXES}, **{s: MMD_MOTION for s in MOTION_SUFFIXES}}
