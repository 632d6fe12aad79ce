"""``mrd-env train``: train a Stable-Baselines3 agent on an mrd-env environment and save it.

The agent acts in the normalised action space ([-1, 1] → the damper's command range) at ``--control-dt``
(10 ms by default: RL at 1 kHz makes very long credit-assignment horizons); observations are normalised
with SB3's ``VecNormalize``, whose statistics are saved next to the model. Evaluate the saved agent with
``mrd-env benchmark --agent PATH`` (it runs through the same evaluation loop as the classical laws).
Long trainings are experiments, not tests.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

ALGOS = ("SAC", "PPO", "TD3")
ENV_IDS = {"quarter_car": "mrd_env/QuarterCar-v0", "building": "mrd_env/ShearBuilding-v0"}


def env_kwargs(plant: str, control_dt: float, episode_seconds: float | None) -> dict:
    kw = dict(action_mode="normalized", control_dt=control_dt)
    if episode_seconds is not None:
        kw["episode_seconds"] = episode_seconds
    return kw


def train(plant: str = "quarter_car", algo: str = "SAC", timesteps: int = 50_000, *, seed: int = 0,
          control_dt: float = 0.01, episode_seconds: float | None = None, out: Path = Path("results/agents"),
          n_envs: int = 1, progress: bool = False) -> Path:
    """Train and save ``<out>/<plant>_<algo>.zip`` (+ ``_vecnormalize.pkl`` and ``.json``); return the zip."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    # every argument is checked before torch and SB3 are imported (seconds) and before an environment is built
    if plant not in ENV_IDS:
        raise ValueError(f"plant must be one of {sorted(ENV_IDS)}, got {plant!r}")
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {algo!r}")
    for name, value, lo in (("timesteps", timesteps, 1), ("seed", seed, 0), ("n_envs", n_envs, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise ValueError(f"{name} must be an int >= {lo}, got {value!r}")
    kw = env_kwargs(plant, control_dt, episode_seconds)
    gym.make(ENV_IDS[plant], **kw).close()  # a bad control_dt or episode_seconds fails here, by name

    import stable_baselines3 as sb3
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    venv = VecNormalize(make_vec_env(ENV_IDS[plant], n_envs=n_envs, seed=seed, env_kwargs=kw),
                        norm_obs=True, norm_reward=True)
    model = getattr(sb3, algo)("MlpPolicy", venv, seed=seed, verbose=0)
    model.learn(total_timesteps=int(timesteps), progress_bar=progress)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"{plant}_{algo}"
    model.save(stem.with_suffix(".zip"))
    venv.save(str(stem) + "_vecnormalize.pkl")
    stem.with_suffix(".json").write_text(json.dumps(
        {"plant": plant, "algo": algo, "timesteps": int(timesteps), "seed": seed, "env_kwargs": kw}, indent=2))
    return stem.with_suffix(".zip")


def agent_metadata(path: str | Path) -> dict:
    """The metadata written next to a saved agent (``<stem>.json``): plant, algorithm, env options. An agent is
    recognised by this file, whatever its name; ``ValueError`` for a missing or unreadable agent."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"agent {path}: no such file")
    meta_path = path.with_suffix(".json")
    if not meta_path.exists():
        raise ValueError(f"agent {path}: its metadata file {meta_path.name} is missing (mrd-env train writes it "
                         "next to the agent)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"agent {path}: {meta_path.name} is not valid JSON ({exc})") from None
    missing = [k for k in ("plant", "algo", "env_kwargs") if not isinstance(meta, dict) or k not in meta]
    if missing:
        raise ValueError(f"agent {path}: {meta_path.name} lacks {missing}: not written by mrd-env train")
    if meta["plant"] not in ENV_IDS:
        raise ValueError(f"agent {path}: unknown plant {meta['plant']!r} in {meta_path.name}")
    return meta


class NormalizedAgent:
    """A saved agent with its observation normalisation: SB3's ``predict`` on raw observations."""

    def __init__(self, path: str | Path):
        import stable_baselines3 as sb3

        path = Path(path)
        meta = agent_metadata(path)
        self.meta = meta
        self.model = getattr(sb3, meta["algo"]).load(path)
        import pickle

        with open(str(path.with_suffix("")) + "_vecnormalize.pkl", "rb") as fh:
            vn = pickle.load(fh)
        self.obs_rms, self.clip, self.eps = vn.obs_rms, vn.clip_obs, vn.epsilon

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        o = np.clip((np.asarray(obs) - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.eps), -self.clip, self.clip)
        return self.model.predict(o.astype(np.float32), state=state, episode_start=episode_start,
                                  deterministic=deterministic)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", choices=sorted(ENV_IDS), default="quarter_car")
    p.add_argument("--algo", choices=ALGOS, default="SAC")
    p.add_argument("--timesteps", type=int, default=50_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--control-dt", type=float, default=0.01, help="agent step in s (multiple of 1 ms)")
    p.add_argument("--episode-seconds", type=float, default=None)
    p.add_argument("--n-envs", type=int, default=1)
    p.add_argument("--out", type=Path, default=Path("results/agents"))
    p.add_argument("--progress", action="store_true", help="show SB3's progress bar")


def run(args: argparse.Namespace) -> int:
    path = train(args.plant, args.algo, args.timesteps, seed=args.seed, control_dt=args.control_dt,
                 episode_seconds=args.episode_seconds, out=args.out, n_envs=args.n_envs, progress=args.progress)
    print(f"saved {path} (evaluate with: mrd-env benchmark --plant {args.plant} --agent {path})")
    return 0
