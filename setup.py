"""Packages and their folders: everything installs under the one import root ``mimicbench``.

The user's folders ``schemas/``, ``datagen/``, ``benchmark/`` and ``baselines/`` sit at the top of
the repository and install as ``mimicbench.schemas``, ``mimicbench.datagen``, ... (setuptools'
``package_dir`` mapping); ``mimicbench/`` holds the geometry core, the runtime floor and the roof
(CLI, commands, pipeline). Everything else is in ``pyproject.toml``.
"""
from setuptools import find_packages, setup

USER_FOLDERS = ("schemas", "datagen", "benchmark", "baselines")

packages = find_packages(include=["mimicbench", "mimicbench.*"])
package_dir = {}
for folder in USER_FOLDERS:
    package_dir[f"mimicbench.{folder}"] = folder
    packages += [f"mimicbench.{name}" for name in find_packages(include=[folder, f"{folder}.*"])]

setup(packages=packages, package_dir=package_dir)
