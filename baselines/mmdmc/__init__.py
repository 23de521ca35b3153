"""The bundled apparel reference: the MMDMC method (Wang et al., "Towards High-Quality 3D Motion
Transfer with Realistic Apparel Animation", ECCV 2024, Section 4), trained on the toolkit's own
simulated apparel data.

One concept a file: :mod:`.geodesic` (vertex-joint geodesic distances G), :mod:`.segmentation`
(f_c), :mod:`.body` (f_s), :mod:`.apparel` (f_d), :mod:`.losses`,
:mod:`.data` (dataset readers), :mod:`.training` (the trainer's stages), :mod:`.config`
(``small`` | ``paper``), :mod:`.method` (the registered methods).
"""
