"""An SB3 or sb3-contrib policy as plain data: its weights as a safetensors file (tensors only: no pickle, no code)
and a JSON description of the network (``agent.json``'s ``"network"``), from which :func:`load_policy` rebuilds
the policy object.

The description names the policy class from an allow-list (:data:`POLICY_CLASSES`: the classes of PPO, A2C, SAC,
TD3, TQC, RecurrentPPO and ARS on vector observations), its observation and action spaces (boxes: shape, dtype,
bounds) and the class's keyword arguments (``net_arch``, the activation by name from :data:`ACTIVATIONS`,
``ortho_init``, ``log_std_init``, ``squash_output``, the LSTM's sizes, ...), each checked for its type and size.
Loading builds that class with those arguments (and a learning-rate schedule the policy never uses: no optimiser
step runs), then loads the weights with ``load_state_dict(strict=True)``: every tensor named and shaped as the
network has it. ``predict`` is then the policy's own, the very method an SB3 model's ``predict`` calls, so the
actions are the SB3 model's bit for bit.
"""
from __future__ import annotations

import importlib
import inspect
import math

import numpy as np

#: The policy classes a description may name: {name: (module, class)}.
POLICY_CLASSES = {
    "ActorCriticPolicy": ("stable_baselines3.common.policies", "ActorCriticPolicy"),      # PPO, A2C (MlpPolicy)
    "SACPolicy": ("stable_baselines3.sac.policies", "SACPolicy"),
    "TD3Policy": ("stable_baselines3.td3.policies", "TD3Policy"),                           # TD3, DDPG
    "TQCPolicy": ("sb3_contrib.tqc.policies", "TQCPolicy"),
    "RecurrentActorCriticPolicy": ("sb3_contrib.common.recurrent.policies", "RecurrentActorCriticPolicy"),
    "ARSPolicy": ("sb3_contrib.ars.policies", "ARSPolicy"),
    "ARSLinearPolicy": ("sb3_contrib.ars.policies", "ARSLinearPolicy"),
}
#: Activation functions by name (``torch.nn`` classes without arguments).
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "SELU", "Mish", "Identity")
#: Feature extractors by name (vector observations only).
EXTRACTORS = ("FlattenExtractor",)
#: The most units of a layer, layers of a network, elements of a space and parameters of a policy a description may
#: ask for (a description is checked before anything is built).
MAX_WIDTH, MAX_DEPTH, MAX_SPACE, MAX_PARAMETERS = 4096, 16, 100_000, 50_000_000
SPACE_DTYPES = ("float32", "float64")


def _flag(name):
    def check(v):
        if v is not None and not isinstance(v, bool):
            raise ValueError(f"{name} must be true, false or null, got {v!r}")
        return v
    return check


def _number(name, lo=-math.inf, hi=math.inf):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
            raise ValueError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
        return float(v)
    return check


def _count(name, lo=1, hi=MAX_WIDTH):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
        return v
    return check


def _layers(v, name="net_arch"):
    if not isinstance(v, list) or len(v) > MAX_DEPTH:
        raise ValueError(f"{name} must be a list of at most {MAX_DEPTH} layer widths, got {v!r}")
    return [_count(f"{name}'s widths", 1, MAX_WIDTH)(w) for w in v]


def _net_arch(v):
    if v is None:
        return None
    if isinstance(v, dict):
        unknown = sorted(set(v) - {"pi", "vf", "qf"})
        if unknown:
            raise ValueError(f"net_arch may have the keys pi, vf, qf, not {unknown}")
        return {k: _layers(w, f"net_arch[{k!r}]") for k, w in v.items()}
    return _layers(v)


def _activation(v):
    if v not in ACTIVATIONS:
        raise ValueError(f"activation_fn must be one of {list(ACTIVATIONS)}, got {v!r}")
    return v


def _extractor(v):
    if v not in EXTRACTORS:
        raise ValueError(f"features_extractor_class must be one of {list(EXTRACTORS)}, got {v!r}")
    return v


def _empty(name):
    def check(v):
        if v not in (None, {}):
            raise ValueError(f"{name} must be empty, got {v!r}")
        return v
    return check


def _lstm_kwargs(v):
    if v is None:
        return None
    if not isinstance(v, dict) or set(v) - {"bias", "dropout"}:
        raise ValueError(f"lstm_kwargs may hold bias and dropout only, got {v!r}")
    out = {}
    if "bias" in v:
        out["bias"] = _flag("lstm_kwargs['bias']")(v["bias"])
    if "dropout" in v:
        out["dropout"] = _number("lstm_kwargs['dropout']", 0.0, 1.0)(v["dropout"])
    return out


#: Every keyword argument a description may give, with its check (the class's own signature decides which apply).
KWARGS = {
    "net_arch": _net_arch, "activation_fn": _activation, "ortho_init": _flag("ortho_init"),
    "use_sde": _flag("use_sde"), "log_std_init": _number("log_std_init", -50, 50), "full_std": _flag("full_std"),
    "use_expln": _flag("use_expln"), "squash_output": _flag("squash_output"),
    "share_features_extractor": _flag("share_features_extractor"), "normalize_images": _flag("normalize_images"),
    "features_extractor_class": _extractor, "features_extractor_kwargs": _empty("features_extractor_kwargs"),
    "clip_mean": _number("clip_mean", 0, 1e6), "n_critics": _count("n_critics", 1, 16),
    "n_quantiles": _count("n_quantiles", 1, 1024), "lstm_hidden_size": _count("lstm_hidden_size"),
    "n_lstm_layers": _count("n_lstm_layers", 1, MAX_DEPTH), "shared_lstm": _flag("shared_lstm"),
    "enable_critic_lstm": _flag("enable_critic_lstm"), "lstm_kwargs": _lstm_kwargs, "with_bias": _flag("with_bias"),
}


def policy_class(name):
    """The class of an allowed policy name; ``ValueError`` naming the allowed ones otherwise."""
    if not isinstance(name, str) or name not in POLICY_CLASSES:
        raise ValueError(f"policy class {name!r} is not one of {sorted(POLICY_CLASSES)}")
    module, attr = POLICY_CLASSES[name]
    try:
        return getattr(importlib.import_module(module), attr)
    except ImportError:
        package = module.split(".")[0].replace("_", "-")
        raise ImportError(f"the policy class {name} needs {package} (pip install {package})") from None


def _bound(values: np.ndarray):
    """A space's bound as JSON: one number when every element is the same, else a list; ±inf as strings."""
    def one(x):
        x = float(x)
        return x if math.isfinite(x) else str(x)   # "inf", "-inf", "nan"
    flat = np.asarray(values).ravel()
    if flat.size and np.all(flat == flat[0]):
        return one(flat[0])
    return [one(x) for x in flat]


def describe_space(space) -> dict:
    """A box space as JSON (type, shape, dtype, low, high)."""
    from gymnasium import spaces

    if type(space) is not spaces.Box:
        raise ValueError(f"only box spaces are supported in an agent's description, got {space}")
    return {"type": "Box", "shape": list(space.shape), "dtype": str(space.dtype), "low": _bound(space.low),
            "high": _bound(space.high)}


def space_of(desc, what: str):
    """The box space of a description written by :func:`describe_space` (checked)."""
    from gymnasium import spaces

    if not isinstance(desc, dict) or desc.get("type") != "Box":
        raise ValueError(f"{what}: a box space description {{type: Box, shape, dtype, low, high}} is required")
    shape = desc.get("shape")
    if not isinstance(shape, list) or not 1 <= len(shape) <= 3 or \
            not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in shape) or \
            math.prod(shape) > MAX_SPACE:
        raise ValueError(f"{what}: shape must be 1 to 3 sizes >= 1 with at most {MAX_SPACE} elements, got {shape!r}")
    if desc.get("dtype") not in SPACE_DTYPES:
        raise ValueError(f"{what}: dtype must be one of {list(SPACE_DTYPES)}, got {desc.get('dtype')!r}")
    n = math.prod(shape)

    def bound(v, name):
        def one(x):
            if isinstance(x, str) and x in ("inf", "-inf", "nan"):
                return float(x)
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise ValueError(f"{what}: {name} must hold numbers (or 'inf', '-inf'), got {x!r}")
            return float(x)
        if isinstance(v, list):
            if len(v) != n:
                raise ValueError(f"{what}: {name} has {len(v)} values for {n} elements")
            return np.array([one(x) for x in v], dtype=np.float64).reshape(shape)
        return np.full(shape, one(v))

    dtype = np.dtype(desc["dtype"])
    low, high = bound(desc.get("low"), "low").astype(dtype), bound(desc.get("high"), "high").astype(dtype)
    return spaces.Box(low=low, high=high, shape=tuple(shape), dtype=dtype)


def _class_kwargs(cls) -> set[str]:
    return set(inspect.signature(cls.__init__).parameters) - {"self", "observation_space", "action_space",
                                                               "lr_schedule", "optimizer_class", "optimizer_kwargs"}


def describe_policy(policy) -> dict:
    """The JSON description of an SB3/sb3-contrib ``policy`` (``model.policy``) that :func:`build_policy`
    rebuilds it from; ``ValueError`` for a policy outside the allow-list (another class, image or dict
    observations, a custom feature extractor or activation)."""
    import torch

    name = type(policy).__name__
    if name not in POLICY_CLASSES or type(policy) is not policy_class(name):
        raise ValueError(f"{type(policy).__module__}.{name} cannot be saved without pickle: the allowed policy "
                         f"classes are {sorted(POLICY_CLASSES)}")
    params = dict(policy._get_constructor_parameters())
    # what the classes leave out of their constructor parameters
    if hasattr(policy, "share_features_extractor"):
        params["share_features_extractor"] = bool(policy.share_features_extractor)
    if name == "RecurrentActorCriticPolicy":
        params.update(lstm_hidden_size=int(policy.lstm_output_dim), n_lstm_layers=int(policy.lstm_actor.num_layers),
                      shared_lstm=bool(policy.shared_lstm), enable_critic_lstm=bool(policy.enable_critic_lstm),
                      lstm_kwargs=dict(policy.lstm_kwargs))
    if name.startswith("ARS"):
        params.update(with_bias=any(k.endswith("bias") for k in policy.state_dict()),
                      squash_output=bool(policy.squash_output))
    kwargs = {}
    for key in sorted(_class_kwargs(type(policy))):
        if key not in params:
            continue
        v = params[key]
        if key == "activation_fn":
            if not (isinstance(v, type) and v.__name__ in ACTIVATIONS and getattr(torch.nn, v.__name__) is v):
                raise ValueError(f"activation {v!r} is not one of {list(ACTIVATIONS)}")
            v = v.__name__
        elif key == "features_extractor_class":
            if not (isinstance(v, type) and v.__name__ in EXTRACTORS):
                raise ValueError(f"feature extractor {v!r} is not one of {list(EXTRACTORS)}")
            v = v.__name__
        elif isinstance(v, tuple):
            v = list(v)
        kwargs[key] = KWARGS[key](v) if key in KWARGS else _unsupported(key, v)
    return {"class": name, "observation_space": describe_space(policy.observation_space),
            "action_space": describe_space(policy.action_space), "kwargs": kwargs}


def _unsupported(key, v):
    raise ValueError(f"policy option {key}={v!r} is not supported in an agent's description")


def _parameter_estimate(kwargs: dict, n_obs: int, n_act: int) -> int:
    """An upper estimate of the parameters a description builds (checked before building it): actor and its
    target, value network, critics and their targets, LSTMs."""
    arch = kwargs.get("net_arch")
    arch = arch if isinstance(arch, dict) else {k: arch if arch is not None else [256, 256] for k in ("pi", "vf", "qf")}
    h = kwargs.get("lstm_hidden_size", 0)
    n_in = max(n_obs, h)

    def mlp(n, layers, n_out):
        dims = [n, *(layers or []), n_out]
        return sum(a * b + b for a, b in zip(dims[:-1], dims[1:]))

    critics = 2 * kwargs.get("n_critics", 2) * mlp(n_in + n_act, arch.get("qf"), kwargs.get("n_quantiles", 1))
    lstm = 2 * 4 * kwargs.get("n_lstm_layers", 1) * h * (n_obs + h + 2)
    return 2 * mlp(n_in, arch.get("pi"), n_act) + mlp(n_in, arch.get("vf"), 1) + critics + lstm


def build_policy(desc):
    """The policy object a description names (weights as initialised: :func:`load_policy` loads them); every
    field checked first (``ValueError`` naming it)."""
    import torch

    if not isinstance(desc, dict):
        raise ValueError("the network description must be a JSON object {class, observation_space, action_space, "
                         "kwargs}")
    cls = policy_class(desc.get("class"))
    obs_space = space_of(desc.get("observation_space"), "observation_space")
    act_space = space_of(desc.get("action_space"), "action_space")
    raw = desc.get("kwargs") or {}
    if not isinstance(raw, dict):
        raise ValueError("the network description's kwargs must be a JSON object")
    allowed = _class_kwargs(cls)
    unknown = sorted(k for k in raw if k not in allowed or k not in KWARGS)
    if unknown:
        raise ValueError(f"policy options {unknown} are not options of {desc['class']} in an agent's description "
                         f"(allowed: {sorted(allowed & set(KWARGS))})")
    kwargs = {k: KWARGS[k](v) for k, v in raw.items()}
    n = _parameter_estimate(kwargs, int(np.prod(obs_space.shape)), int(np.prod(act_space.shape)))
    if n > MAX_PARAMETERS:
        raise ValueError(f"the network description asks for about {n:.3g} parameters (limit {MAX_PARAMETERS:.0e})")
    if "activation_fn" in kwargs:
        kwargs["activation_fn"] = getattr(torch.nn, kwargs["activation_fn"])
    if "features_extractor_class" in kwargs:
        from stable_baselines3.common import torch_layers
        kwargs["features_extractor_class"] = getattr(torch_layers, kwargs["features_extractor_class"])
    if "lr_schedule" in inspect.signature(cls.__init__).parameters:
        kwargs["lr_schedule"] = _no_learning
    try:
        policy = cls(obs_space, act_space, **kwargs)
    except (TypeError, AssertionError, ValueError) as exc:
        raise ValueError(f"the network description does not build a {desc['class']}: {exc}") from None
    policy.set_training_mode(False)
    return policy


def _no_learning(_progress: float) -> float:
    return 0.0  # the learning rate of an optimiser that never steps


def policy_bytes(policy) -> bytes:
    """The policy's weights (its ``state_dict``) as a safetensors file's bytes."""
    from safetensors.torch import save

    tensors = {k: v.detach().to("cpu").contiguous().clone() for k, v in policy.state_dict().items()}
    return save(tensors, metadata={"format": "pt"})


def load_policy(desc, data: bytes, what: str = "policy"):
    """The policy of description ``desc`` with the weights of the safetensors bytes ``data``: tensors only (no
    pickle); every tensor the network has, named and shaped as it has them (``ValueError`` otherwise)."""
    from safetensors import SafetensorError
    from safetensors.torch import load

    policy = build_policy(desc)
    try:
        tensors = load(data)
    except (SafetensorError, ValueError, RuntimeError) as exc:
        raise ValueError(f"{what} is not a safetensors file ({exc})") from None
    try:
        policy.load_state_dict(tensors, strict=True)
    except RuntimeError as exc:
        detail = " ".join(str(exc).split())[:300]
        raise ValueError(f"{what} does not hold the weights of the network agent.json describes: {detail}") from None
    policy.set_training_mode(False)
    return policy


class PolicyModel:
    """A policy rebuilt from its description and weights, with an SB3 model's interface for acting: ``predict``
    (the policy's own, which ``model.predict`` calls), ``policy``, ``observation_space``, ``action_space``, and the
    policy's networks as attributes (``actor``, ``critic``, ...), as on the algorithm."""

    def __init__(self, algo: str, policy):
        self.algo = algo
        self.policy = policy

    @property
    def observation_space(self):
        return self.policy.observation_space

    @property
    def action_space(self):
        return self.policy.action_space

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = False):
        return self.policy.predict(observation, state, episode_start, deterministic)

    def __getattr__(self, name):
        if name == "policy":  # not yet set (copy, unpickling)
            raise AttributeError(name)
        return getattr(self.policy, name)

    def __repr__(self) -> str:
        return f"PolicyModel({self.algo}, {type(self.policy).__name__})"
