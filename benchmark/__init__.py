"""The benchmark: adapter API, registry, cases, metrics, evaluator, results and leaderboard.

A method is any :class:`mimicbench.benchmark.method.PoseTransferMethod` registered by name
(:mod:`mimicbench.benchmark.registry`); the evaluator never imports a method by module.
"""
