"""The integration scheme's constants, shared by the Python side and the compiled kernel (see
:mod:`mrd_env.stepping`)."""
from __future__ import annotations

import math

#: γ of Alexander's two-stage SDIRK (L-stable, stiffly accurate, order 2).
GAMMA = 1.0 - 1.0 / math.sqrt(2.0)

#: Default local error tolerances (SI units): tighter ones buy accuracy that the models do not have at the price
#: of sub-steps (measured on the quarter car on a class-C road: rtol 1e-2 → 1.7 sub-steps per step, force
#: NRMSE 0.05 % against Radau; 1e-1 → 1.05 sub-steps, 0.12 %; no error control → 2.9 %).
RTOL = 1e-1
ATOL = 1e-5

#: Default budget of sub-steps per step (the environments' steps are 1 ms; a longer step gets as many per ms).
MAX_SUBSTEPS = 8

# What one step of one system returns (the kernel's ``macro_step``).
OK = 0
NONFINITE = 1
NO_CONVERGENCE = 2


def max_level_of(max_substeps: int) -> int:
    """k such that 2^k is the first power of two >= ``max_substeps``."""
    return max(0, int(math.ceil(math.log2(max_substeps) - 1e-12)))
