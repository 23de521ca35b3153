"""What running a job needs, independent of any stage: user errors, the name registry, options
dataclasses from argparse, argument types, the stage summary and the address-space limit.
With :mod:`mimicbench.engines` and :mod:`mimicbench.training` it is the floor above the geometry
core and below the datagen stages."""
