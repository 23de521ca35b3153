"""The built wheel claims one import name, ``mimicbench``, and runs beside a package that owns ``baselines``.

The wheel comes from ``pip wheel .``; its file list is read from the zip (an independent reader of
what pip would install). The clean environment is a fresh ``venv`` without pip whose only link to
this checkout's dependencies is a ``.pth`` line naming their site-packages folder (a ``.pth`` line
adds a path; the editable install's own ``.pth`` hook there is not run), so the package under test
is the wheel's copy and nothing else.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OTHER_BASELINES = "an unrelated distribution's module"


def source_copy(dest: Path) -> Path:
    """The checkout's files that git tracks or would track, copied to ``dest`` (setuptools builds in the
    source folder's ``build/``, whose leftovers from an earlier build would enter the wheel)."""
    listed = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, check=True,
                            capture_output=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


def build_wheel(out: Path) -> Path:
    source = source_copy(out / "source")
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(source), "--no-deps", "--no-build-isolation",
                    "--quiet", "--wheel-dir", str(out)], check=True, cwd=out)
    (wheel,) = out.glob("mimicbench-*.whl")
    return wheel


def top_level_names(wheel: Path) -> set[str]:
    """The first path component of every file in the wheel, less its .dist-info folder."""
    with zipfile.ZipFile(wheel) as zf:
        firsts = {name.split("/")[0] for name in zf.namelist()}
    return {Path(f).stem if f.endswith(".py") else f for f in firsts if not f.endswith(".dist-info")}


def clean_environment(folder: Path, wheel: Path) -> Path:
    """A venv holding the wheel's files and a package named ``baselines`` that is not ours; its python."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True)
    python = folder / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    with zipfile.ZipFile(wheel) as zf:
        zf.extractall(site)
    (site / "baselines").mkdir()
    (site / "baselines" / "__init__.py").write_text(f"OWNER = {OTHER_BASELINES!r}\n")
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return python


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    return build_wheel(tmp_path_factory.mktemp("wheel"))


def test_the_wheel_claims_only_the_mimicbench_import_name(wheel):
    assert top_level_names(wheel) == {"mimicbench"}
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    assert {"mimicbench/datagen/zoo/dataset.py", "mimicbench/baselines/npt/checkpoints/npt.safetensors",
            "mimicbench/schemas/FORMAT.md", "mimicbench/geometry/quaternion.py"} <= names


@pytest.mark.slow
def test_the_installed_wheel_runs_the_demo_beside_another_baselines(wheel, tmp_path):
    python = clean_environment(tmp_path / "env", wheel)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    work = tmp_path / "work"
    work.mkdir()
    probe = ("import baselines, mimicbench.baselines.npt.method as npt, mimicbench.benchmark.registry as r;"
             "print(baselines.OWNER); print(npt.__file__); print(r.get_method('nearest_joint').metadata.name)")
    out = subprocess.run([str(python), "-c", probe], capture_output=True, text=True, env=env, cwd=work, check=True)
    owner, npt_file, method = out.stdout.splitlines()
    assert owner == OTHER_BASELINES and method == "nearest_joint"
    assert Path(npt_file).is_relative_to(tmp_path / "env"), npt_file
    demo = subprocess.run([str(python), "-m", "mimicbench", "demo", "--out", str(work / "demo"), "--characters", "6",
                           "--h2h-poses", "1", "--cct-pairs", "2", "--cct-poses", "1", "--apparel-windows", "1"],
                          capture_output=True, text=True, env=env, cwd=work)
    assert demo.returncode == 0, demo.stderr[-3000:]
    assert (work / "demo" / "results").exists() or any((work / "demo").rglob("leaderboard.md")), demo.stdout[-2000:]
