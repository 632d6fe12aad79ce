"""The ``mrd-env`` commands: one module per verb (``experiments/cli.py`` lists them), each exposing
``add_arguments(parser)`` and ``run(args) -> int``. A command imports :mod:`experiments.common` and the library, never
another command."""
