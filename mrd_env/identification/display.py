"""Values shown in error messages as the user wrote them."""
from __future__ import annotations

import numpy as np


def shown(value) -> str:
    """``repr(value)``, a NumPy scalar as the Python number it holds (``0.002``, not ``np.float64(0.002)``)."""
    return repr(value.item() if isinstance(value, np.generic) else value)
