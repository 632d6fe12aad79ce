"""Command line and experiment scripts of mrd-env (``mrd-env --help``)."""
