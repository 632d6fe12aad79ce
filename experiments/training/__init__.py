"""The training algorithms behind ``mrd-env train``: Stable-Baselines3's bridge (:mod:`.sb3_trainer`), CMA-ES
(:mod:`.evolution`), SHAC through the JAX twin (:mod:`.shac`), PPO inside one jit (:mod:`.ppo_jax`), and what they
share (:mod:`.trainers`, warm starts, the actor warm-up, learning curves)."""
