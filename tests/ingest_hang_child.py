"""A Blender ingest child for tests: like :mod:`mimicbench.datagen.ingest.blender_child --serve`, but an asset
whose file name contains ``Hanging`` first writes a partial result (a stand-in for the arrays a
child writes before it is stopped) and then hangs, and one containing ``Crashing`` kills the
process. The runner must fail those jobs, drop what they wrote, and go on with a fresh process."""
import os
import sys
import time

import bpy  # noqa: F401  (first, as in the real child)
import numpy as np

from mimicbench.datagen.ingest import blender_child

_real = blender_child.ingest_one


def _ingest_one(path, out_npz, options=None):
    name = os.path.basename(path)
    if "Hanging" in name:
        np.savez(out_npz, vertices=np.zeros((3, 3)))
        with open(out_npz[: -len(".npz")] + ".json", "w") as f:
            f.write('{"status": "ok", "bone_names": [], "clips": []}')
        time.sleep(3600)
    if "Crashing" in name:
        os._exit(3)
    return _real(path, out_npz, options)


blender_child.ingest_one = _ingest_one

if __name__ == "__main__":
    sys.exit(blender_child.main())
