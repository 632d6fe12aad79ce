"""How fast, how much memory, how accurate: scripts, not tests, run as
``python -m experiments.measurements.<speed|memory|accuracy>.<name>``. Speed figures are ratios to a reference
measured in the same run, medians of repeats, with the machine's load printed beside them."""
