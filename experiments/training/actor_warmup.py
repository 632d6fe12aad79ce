"""The actor's pace in the off-policy actor-critic algorithms (SAC, TD3, TQC), two hyperparameters of ``mrd-env
train``:

* ``actor_warmup_steps: K`` leaves the actor (and SAC's and TQC's entropy coefficient, when it is learned)
  untouched for the first K gradient steps, while the critics and their targets train as usual;
* ``actor_learning_rate: x`` gives the actor's optimizer its own learning rate (a number > 0; SB3 gives the actor
  and the critic the one ``learning_rate``, which the critic keeps).

Why: a residual agent starts exactly at its law (:func:`controllers.residual.zero_policy_output`), but its critic
starts as an untrained function; from the first gradient step the actor follows that function's action gradient and
leaves the law before the critic knows anything (docs/rl-agents.md). With the warm-up, the critic first learns the
value of the behaviour that fills the replay buffer — the law plus the exploration noise — and the actor only moves
once that value exists. (On the quarter car this did not keep TD3 at its law: after 3·10⁴ gradient steps the
critic's action gradient was still no better than a random sign; docs/rl-agents.md.)

How: SB3's ``train(gradient_steps, batch_size)`` runs unchanged (no copy of its loop); during the warm-up the
optimizer steps of the actor and of the entropy coefficient do nothing, so neither the parameters nor the Adam
moments change, and the losses are still computed and logged. Everything else — the critic's updates, TD3's
``policy_delay`` and target-policy smoothing, the Polyak updates of the target critics — is SB3's own. The actor's
target network follows the frozen actor, so it does not move either. A call of ``train`` that straddles the end of
the warm-up is split in two at the boundary. The gradient steps are counted by SB3's ``_n_updates`` (every
gradient step of SAC, TD3 and TQC, whatever ``policy_delay``): with ``learning_starts`` L, ``train_freq`` f (in
vector steps), ``gradient_steps`` g and n environments the actor first moves after about L + K·f·n/g environment
steps.

The actor's learning rate is set after SB3's ``_update_learning_rate`` has given every optimizer the schedule's.

A model trained this way is saved and loaded as the plain algorithm (``agent.json`` names SAC, TD3 or TQC): these
options change the training only.
"""
from __future__ import annotations

from contextlib import contextmanager

#: The hyperparameters' names, and the ``--algo`` values they apply to (actor-critic algorithms with a replay buffer).
OPTION = "actor_warmup_steps"
LR_OPTION = "actor_learning_rate"
ALGOS = ("sac", "td3", "tqc")

_CLASSES: dict[type, type] = {}


def _off_policy_only(option: str, algo: str) -> None:
    if algo not in ALGOS:
        raise ValueError(f"hyperparameter {option} applies to the off-policy algorithms {list(ALGOS)}, not to {algo}")


def check_actor_warmup(algo: str, hyper: dict) -> int:
    """The entry's number of warm-up gradient steps (0: none); ``ValueError`` naming the option and its valid
    values for a negative or non-integer value, or on an algorithm without a critic to warm up."""
    value = hyper.get(OPTION)
    if value is None:
        return 0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0 or float(value) != int(value):
        raise ValueError(f"hyperparameter {OPTION} must be an integer >= 0 (gradient steps with the actor frozen), "
                         f"got {value!r}")
    _off_policy_only(OPTION, algo)
    return int(value)


def check_actor_learning_rate(algo: str, hyper: dict) -> float | None:
    """The entry's learning rate of the actor (None: SB3's ``learning_rate``, as the critic's); ``ValueError``
    naming the option and its valid values for anything but a number > 0, or on an algorithm without a critic."""
    value = hyper.get(LR_OPTION)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < float("inf"):
        raise ValueError(f"hyperparameter {LR_OPTION} must be a number > 0 (the actor's own learning rate), "
                         f"got {value!r}")
    _off_policy_only(LR_OPTION, algo)
    return float(value)


def actor_options(algo: str, hyper: dict) -> dict:
    """{attribute: value} of :class:`ActorWarmup` the entry sets (empty: the plain algorithm will do)."""
    out = {OPTION: check_actor_warmup(algo, hyper), LR_OPTION: check_actor_learning_rate(algo, hyper)}
    return {k: v for k, v in out.items() if v}


@contextmanager
def _frozen(optimizers):
    """The optimizers' ``step`` does nothing inside the block (their parameters and moments stay as they are)."""
    optimizers = [o for o in optimizers if o is not None]
    for opt in optimizers:
        opt.step = _no_step
    try:
        yield
    finally:
        for opt in optimizers:
            del opt.step  # the class's own step again


def _no_step(closure=None):
    return None


class ActorWarmup:
    """Mixin before an SB3 off-policy actor-critic class (:func:`with_actor_warmup`): see the module docstring."""

    #: gradient steps with the actor (and a learned entropy coefficient) frozen; 0: none
    actor_warmup_steps: int = 0
    #: the actor optimizer's learning rate (None: the algorithm's ``learning_rate``)
    actor_learning_rate: float | None = None

    def _excluded_save_params(self) -> list[str]:  # training options, not the model's
        return [*super()._excluded_save_params(), OPTION, LR_OPTION]

    def _update_learning_rate(self, optimizers) -> None:
        super()._update_learning_rate(optimizers)
        if self.actor_learning_rate is not None:
            from stable_baselines3.common.utils import update_learning_rate

            update_learning_rate(self.actor.optimizer, self.actor_learning_rate)
            self.logger.record("train/actor_learning_rate", self.actor_learning_rate)

    def _frozen_optimizers(self) -> list:
        return [self.actor.optimizer, getattr(self, "ent_coef_optimizer", None)]

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        left = int(self.actor_warmup_steps) - int(self._n_updates)
        if left <= 0:
            return super().train(gradient_steps, batch_size)
        warm = min(left, gradient_steps)
        with _frozen(self._frozen_optimizers()):
            super().train(warm, batch_size)
        if gradient_steps > warm:
            super().train(gradient_steps - warm, batch_size)


def with_actor_warmup(cls: type) -> type:
    """``cls`` (SAC, TD3, TQC) with the actor warm-up (:class:`ActorWarmup`); the same subclass on every call."""
    if cls not in _CLASSES:
        _CLASSES[cls] = type(cls.__name__, (ActorWarmup, cls), {"__module__": __name__,
                                                                   "__doc__": f"{cls.__name__} with the actor warm-up"})
    return _CLASSES[cls]
