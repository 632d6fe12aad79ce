"""The test suite: one folder per package or subpackage it tests (``tests/dampers/``, ``tests/envs/``, ...,
``tests/controllers/``, ``tests/experiments/``), the cross-cutting checks and the tests of the library's top-level
modules here. Every folder is a package (``tests.<folder>``): a folder without ``__init__.py`` on ``sys.path`` would
stand in for the ``controllers`` or ``experiments`` package of the same name (a namespace package) wherever the
repository root is not on ``sys.path``."""
