"""Teaching labs: jupytext percent notebooks (``labN_<topic>.py``) that also run as plain scripts.

See ``experiments/labs/README.md``. :mod:`.labkit` holds what every lab shares: the output folder, figure saving
and the instructor's checks.
"""
