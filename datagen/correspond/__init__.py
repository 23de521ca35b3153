"""Ground-truth correspondences between characters' keypoints (MimiCAT Sec. 3, and beyond).

Bone names are canonicalised (:mod:`.canonical`), embedded with a text encoder
(:mod:`.encoders`: MiniLM offline by default, CLIP through open_clip) and compared by cosine
similarity S_cos. The method (:mod:`.methods`) is chosen by name: ``text`` is the paper's
(S_cos, Hungarian M_hung, Sinkhorn M_sink); ``structure`` (the default) adds what the skeleton
says (:mod:`.structure`) and a no-match threshold. Matrices are computed in batches
(:mod:`.batched`) for sampled or all pairs of each split (:mod:`.sampling`), and scored against
the zoo's hidden bone roles (:mod:`.report`) through the cross-category role map (:mod:`.roles`).
"""
from __future__ import annotations
