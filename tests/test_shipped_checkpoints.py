"""The shipped checkpoints are tied to their methods' versions.

Results are stored per method version (``RESULTS/<method>/<version>/``) and a re-run resumes into
that folder, so new weights under an old version would mix two models' rows in one leaderboard
line. Whoever retrains a shipped checkpoint must bump the versions of the methods that read it and
record the new digest here.
"""
import hashlib
from pathlib import Path

import pytest

from mimicbench.baselines.mimicat.method import BUNDLED, Mimicat, MimicatInitOnly, MimicatNaiveAvg, MimicatNoPrior
from mimicbench.baselines.mmdmc.method import CHECKPOINTS, Mmdmc, MmdmcBodyOnly, MmdmcGtMask, MmdmcNoApparel
from mimicbench.baselines.cgt.method import Cgt, CgtNoAttention
from mimicbench.baselines.npt.method import Npt, NptConstantCode
from mimicbench.baselines.sfpt.method import Sfpt, SfptKabschOnly

# version of every method reading the folder -> sha256 over its .safetensors files (sorted by name,
# each as name + NUL + bytes)
SHIPPED = {
    "mimicat": (BUNDLED, (Mimicat, MimicatNaiveAvg, MimicatNoPrior, MimicatInitOnly), "11",
                "f46b59fcc13c4bf0224244f17e1bac9b87c4f70c56c46bdafb6ff5c8e416b3ff"),
    "mmdmc": (CHECKPOINTS, (Mmdmc, MmdmcBodyOnly, MmdmcNoApparel, MmdmcGtMask), "10",
              "dc0d47f4b628021125659154d214ce3732bc043c8f252b475592a8c6cca472aa"),
    "cgt": (Cgt.shipped, (Cgt, CgtNoAttention), "5", "a51c551865725fcc97ea667551970467e1f6ba8ffd0df215bcdfd76876f2186b"),
    "npt": (Npt.shipped, (Npt, NptConstantCode), "6",
            "6494bcdaf4a9aaf532ae62cd82cbaa4dc9801072ee960c6ffaf6e425cea8fc1c"),
    "sfpt": (Sfpt.shipped, (Sfpt, SfptKabschOnly), "5",
             "ef5c00014737bdf7de6f1bb815daf0cd848817ece02a9775268d9ad4ec634a5c"),
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

    from mimicbench.baselines.mmdmc.method import ENV as MMDMC_ENV

    by_hand = lambda files: hashlib.sha256(json.dumps(  # noqa: E731
        {k: hashlib.sha256(Path(v).read_bytes()).hexdigest() for k, v in files.items()},
        sort_keys=True, separators=(",", ":")).encode()).hexdigest()
    shipped = {"shape": BUNDLED / "shape.safetensors", "corr": BUNDLED / "corr.safetensors",
               "transfer": BUNDLED / "transfer.safetensors", "range": BUNDLED / "range.safetensors"}
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
    (run / "apparel.safetensors").write_bytes(b"other")
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
    # the bound docs/methods/published-deviations.md states: each shipped checkpoint below 2 MB
    for method in (Npt, Cgt, Sfpt):
        size = (method.shipped / f"{method.stage}.safetensors").stat().st_size
        assert size < 2 * 10**6, (method.metadata.name, size)
