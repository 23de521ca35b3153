"""Neural Pose Transfer (Wang et al., CVPR 2020), re-implemented from the paper."""
