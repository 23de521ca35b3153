"""Text-guided ground-truth correspondences between characters' keypoints (MimiCAT Sec. 3).

Bone names are canonicalised (:mod:`.canonical`), embedded with a text encoder
(:mod:`.encoders`: MiniLM offline by default, CLIP through open_clip), compared by cosine
similarity S_cos, matched one-to-one by the Hungarian algorithm (M_hung) and softly by Sinkhorn
(M_sink) in batches (:mod:`.batched`), for sampled or all pairs of each split (:mod:`.sampling`),
and scored against the zoo's hidden bone roles (:mod:`.report`).
"""
from datagen.correspond.canonical import canonicalize_bone_name, canonicalize_names
from datagen.correspond.stage import correspond_dataset, correspondence_for_names

__all__ = ["canonicalize_bone_name", "canonicalize_names", "correspond_dataset", "correspondence_for_names"]
