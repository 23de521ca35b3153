"""The shipped checkpoints are tied to their methods' versions.

Results are stored per method version (``RESULTS/<method>/<version>/``) and a re-run resumes into
that folder, so new weights under an old version would mix two models' rows in one leaderboard
line. Whoever retrains a shipped checkpoint must bump the versions of the methods that read it and
record the new digest here.
"""
import hashlib
from pathlib import Path

import pytest

from baselines.mimicat.method import BUNDLED, Mimicat, MimicatInitOnly, MimicatNaiveAvg, MimicatNoPrior
from baselines.mmdmc.method import CHECKPOINTS, Mmdmc, MmdmcBodyOnly, MmdmcGtMask, MmdmcNoRefine
from baselines.cgt.method import Cgt
from baselines.npt.method import Npt
from baselines.sfpt.method import Sfpt

# version of every method reading the folder -> sha256 over its .safetensors files (sorted by name,
# each as name + NUL + bytes)
SHIPPED = {
    "mimicat": (BUNDLED, (Mimicat, MimicatNaiveAvg, MimicatNoPrior, MimicatInitOnly), "7",
                "a674302154d6e723bf0de4ee9dad7f63eb88197ad7e9e82fc59db920213f81d9"),
    "mmdmc": (CHECKPOINTS, (Mmdmc, MmdmcBodyOnly, MmdmcNoRefine, MmdmcGtMask), "9",
              "c0ba1a01ddb5ad9cf3f33002b62926c2d7c4ec92bb1100d3b1d5b6321c0ad3af"),
    "cgt": (Cgt.shipped, (Cgt,), "3", "290c85714ab2869ea1c1865a3cd14702c15534f723ed1bcbe3f90bb1a7f39681"),
    "npt": (Npt.shipped, (Npt,), "4", "c950a63dcf602a3b69981684a8f11c9f3af2a76db68e76010c3dddf94424fefe"),
    "sfpt": (Sfpt.shipped, (Sfpt,), "1", "4e72e1e72735edfdcd6cae92ec24c38da013d46aa8cbd06565bdf912bee7e89a"),
}


def folder_digest(folder: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(Path(folder).glob("*.safetensors")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


@pytest.mark.parametrize("family", sorted(SHIPPED))
def test_shipped_weights_match_the_recorded_digest_of_their_version(family):
    folder, methods, version, digest = SHIPPED[family]
    assert any(Path(folder).glob("*.safetensors")), f"{folder}: no shipped weights"
    assert [m.metadata.version for m in methods] == [version] * len(methods), (
        f"every {family} method should be version {version}")
    assert folder_digest(folder) == digest, (
        f"{folder}: the shipped weights changed; bump the version of {[m.metadata.name for m in methods]} "
        f"and record the new digest {folder_digest(folder)} here")


def test_methods_fingerprint_the_weights_they_load(tmp_path, monkeypatch):
    """Results record these fingerprints (meta.json 'weights'), so a user's checkpoint never
    resumes into the shipped weights' rows: a copied folder is the same weights, one changed
    byte is not."""
    import json
    import shutil

    from baselines.mmdmc.method import ENV as MMDMC_ENV

    by_hand = lambda files: hashlib.sha256(json.dumps(  # noqa: E731
        {k: hashlib.sha256(Path(v).read_bytes()).hexdigest() for k, v in files.items()},
        sort_keys=True, separators=(",", ":")).encode()).hexdigest()
    shipped = {"shape": BUNDLED / "shape.safetensors", "corr": BUNDLED / "corr.safetensors",
               "transfer": BUNDLED / "transfer.safetensors"}
    assert Mimicat().weights_fingerprint() == by_hand(shipped)
    assert MimicatNoPrior().weights_fingerprint() != Mimicat().weights_fingerprint()
    copy = tmp_path / "mimicat"
    shutil.copytree(BUNDLED, copy)
    assert Mimicat(checkpoint=copy).weights_fingerprint() == Mimicat().weights_fingerprint()
    data = bytearray((copy / "corr.safetensors").read_bytes())
    data[-1] ^= 1
    (copy / "corr.safetensors").write_bytes(bytes(data))
    assert Mimicat(checkpoint=copy).weights_fingerprint() != Mimicat().weights_fingerprint()

    full, body_only = Mmdmc().weights_fingerprint(), MmdmcBodyOnly().weights_fingerprint()
    assert body_only == by_hand({"body": CHECKPOINTS / "body.safetensors"}) and full != body_only
    run = tmp_path / "mmdmc"
    shutil.copytree(CHECKPOINTS, run)
    monkeypatch.setenv(MMDMC_ENV, str(run))
    assert Mmdmc().weights_fingerprint() == full
    (run / "refine.safetensors").write_bytes(b"other")
    assert Mmdmc().weights_fingerprint() != full and MmdmcBodyOnly().weights_fingerprint() == body_only

    for method in (Npt, Cgt, Sfpt):  # one file each, shipped as <stage>.safetensors or a run's <stage>/model.safetensors
        shipped_file = method.shipped / f"{method.stage}.safetensors"
        assert method().weights_fingerprint() == by_hand({method.stage: shipped_file})
        run = tmp_path / method.stage / method.stage
        run.mkdir(parents=True)
        shutil.copy(shipped_file, run / "model.safetensors")
        monkeypatch.setenv(method.env, str(run.parent))
        assert method().weights_fingerprint() == by_hand({method.stage: shipped_file})
        data = bytearray(shipped_file.read_bytes())
        data[-1] ^= 1
        (run / "model.safetensors").write_bytes(bytes(data))
        assert method().weights_fingerprint() != by_hand({method.stage: shipped_file})
        monkeypatch.delenv(method.env)


def test_shipped_published_baselines_are_small():
    # issue 34's bound: each shipped checkpoint below 20 MB (npt v4 is 13.9 MB: the large preset, 384 wide)
    for method in (Npt, Cgt, Sfpt):
        size = (method.shipped / f"{method.stage}.safetensors").stat().st_size
        assert size < 20 * 10**6, (method.metadata.name, size)
