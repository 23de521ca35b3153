"""The geometry core: quaternions, kinematics, skinning, Kabsch fits, transform estimation, the
joint-fit pose read-off, rotation averaging, Sinkhorn and Hungarian matching, mesh helpers and
array-shape checks. It imports only :mod:`mimicbench.schemas`; every other floor builds on it."""
