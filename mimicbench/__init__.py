"""mimicbench: datasets and benchmarks for 3D character pose transfer.

The top-level package is the small shared core: quaternions, kinematics, skinning, transform
estimation, rotation averaging, Sinkhorn, Hungarian matching and mesh helpers, plus the CLI.
"""
__version__ = "0.1.0"
