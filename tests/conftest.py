import os

os.environ.setdefault("MPLBACKEND", "Agg")
# the suite compiles in its own processes (no background compilers, no interpreted steps where tests time or
# count); tests/test_first_use.py switches the interpreted first use on where it tests it
os.environ.setdefault("MRD_ENV_FIRST_USE", "wait")
