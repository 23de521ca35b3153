"""Validity probes: a right transfer and its corruptions in known ways, for ``bench validity``.

A score that cannot tell a corrupted transfer from its uncorrupted method cannot rank methods on
what it corrupts. The probes are instruments, not methods to compete with: those that read the
characters' hidden roles (:data:`mimicbench.benchmark.protocols.base.HIDDEN_ROLES_TAG`) are never on the
leaderboard's ranking of methods.
"""
