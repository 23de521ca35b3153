"""A Blender ingest child for tests that binds every clip's actions without their slots, as the
ingest once did for FBX (it looked for a slot named after the object, which Blender 4.5's FBX
importer never makes): only the action the importer assigned itself still plays. The ingest's
fresh-import check must fail those clips instead of storing the rest pose."""
import sys

import bpy  # noqa: F401  (first, as in the real child)

from mimicbench.datagen.ingest import blender_child

_real = blender_child._assign


def _assign_without_slots(bindings):
    _real([(action, obj, None) for action, obj, _ in bindings])


blender_child._assign = _assign_without_slots

if __name__ == "__main__":
    sys.exit(blender_child.main())
