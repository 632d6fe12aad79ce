"""The ``mrd-env`` commands: one module per verb (``experiments/cli.py`` lists them), each exposing
``add_arguments(parser)`` and ``run(args) -> int``. A command imports :mod:`experiments.common`, :mod:`experiments.benchmark`, :mod:`experiments.training` and the library, never
another command."""
