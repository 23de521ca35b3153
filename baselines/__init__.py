"""Methods behind the adapter API: non-learned baselines (identity, name_copy, nearest_joint,
text_soft). They are found through :mod:`benchmark.registry`, never imported by the harness."""
