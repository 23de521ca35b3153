"""Skeleton-free Pose Transfer (Liao et al., ECCV 2022), re-implemented from the paper."""
