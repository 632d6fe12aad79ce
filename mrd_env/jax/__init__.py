"""A JAX twin of the physics (optional: ``pip install mrd-env[jax]``; nothing else in the project needs it).

Importing it switches JAX to float64 (``jax_enable_x64``: the schemes need it; set before any array is made) and,
unless the process chose one already, points JAX's persistent compilation cache at the project's cache folder
(:func:`mrd_env.caches.cache_folder` ``("jax")``), so that a later process loads what an earlier one compiled.
See ``docs/jax.md``: every plant's environment made from its own assembly (:mod:`.env`) and its Gymnasium
``VectorEnv`` (:mod:`.vector`), the stepping scheme (:mod:`.scheme`), the dampers (:mod:`.dampers`), any system over
a record (:mod:`.simulate`), the clairvoyant by gradient (:mod:`.clairvoyant`).
"""
from __future__ import annotations

import jax

from ..caches import cache_folder

jax.config.update("jax_enable_x64", True)
if not jax.config.jax_compilation_cache_dir:
    jax.config.update("jax_compilation_cache_dir", str(cache_folder("jax")))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)

from . import dampers, scheme, simulate  # noqa: E402

__all__ = ["dampers", "scheme", "simulate"]
