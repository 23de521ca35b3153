"""The benchmark: adapter API, registry, cases, metrics, evaluator, results and leaderboard.

A method is any :class:`benchmark.method.PoseTransferMethod` registered by name
(:mod:`benchmark.registry`); the evaluator never imports a method by module.
"""
