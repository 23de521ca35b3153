"""mimicbench: datasets and benchmarks for 3D character pose transfer.

One import root. Floors, lowest first: :mod:`mimicbench.schemas` (the data contract),
:mod:`mimicbench.geometry` (the numeric core), :mod:`mimicbench.runtime` with
:mod:`mimicbench.engines` and :mod:`mimicbench.training`, :mod:`mimicbench.datagen` (dataset
stages), :mod:`mimicbench.benchmark` (protocols, metrics, evaluator), :mod:`mimicbench.baselines`
(the bundled methods), and the roof: :mod:`mimicbench.cli`, :mod:`mimicbench.commands`,
:mod:`mimicbench.pipeline`. This module holds only the version.
"""
__version__ = "0.1.0"
