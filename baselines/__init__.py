"""Methods behind the adapter API: non-learned baselines (identity, name_copy, nearest_joint,
text_soft; for the apparel protocol lbs_kinematic and body_only). They are found through :mod:`mimicbench.benchmark.registry`, never imported by the harness."""
