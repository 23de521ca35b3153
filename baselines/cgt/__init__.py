"""CGT, the correspondence-free geometric transformer (Chen et al., AAAI 2022), re-implemented from the paper."""
