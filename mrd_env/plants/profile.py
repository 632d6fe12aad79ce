"""What the experiments know about a plant (:class:`PlantProfile`): its environment options, what agents train on,
the labs' held-out scenarios, the laws and MPC rows that apply, the laws that warm-start the clairvoyant. Each plant
declares its profile in its folder (``mrd_env/plants/<plant>/profile.py``: ``PROFILE``); the commands (``train``,
``tune``, ``benchmark``, ``score``, ``suite build``), the labs and the measurements read it and never branch on a
plant's name. Each field's comment names what reads it.

A profile is data: the library holds it without importing the experiments. It pickles by reference (its plant's
name), so that the commands hand it to their workers as it is.
"""
from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass, field
from typing import Callable, Mapping

from .spec import PlantSpec

#: A test case of a plant: (name, environment options, seeded) — seeded cases run once per test seed, the others
#: (a recorded earthquake, a bump) once.
TestCase = tuple[str, dict, bool]


@dataclass(frozen=True)
class PlantOption:
    """An option of a plant that the commands offer (``--<name> VALUE``, e.g. the building's ``--storeys 6``)."""

    name: str            #: the option without its dashes
    help: str
    metavar: str = "VALUE"


#: The plant option every plant offers: the damper model of every damper (its environment option ``damper``).
DAMPER_OPTION = PlantOption("damper", "damper model name (e.g. spencer_dyke) or preset file (.json) of every damper",
                            "MODEL")


@dataclass(frozen=True)
class PlantProfile:
    """One plant as the experiments see it (see the module docstring)."""

    spec: PlantSpec                #: the plant (its name, ids and title)
    #: the environment options of the plant every experiment runs (the building's damper storey): the labs' held-out
    #: scenarios are on it (``experiments.common.scenarios.held_out_scenarios``)
    options: dict
    #: the training distribution as environment options (a new disturbance per episode): what ``mrd-env train``
    #: and ``tune`` train on and the validation episodes (``experiments.common.scenarios.validation``)
    training: dict
    #: the environment option holding the disturbance ("road", "ground_motion"): the trainers replace it
    #: (``experiments.training.trainers``)
    disturbance_key: str
    #: ``tests(plant_options, quick) -> [TestCase]``: the labs' held-out scenarios on ``plant_options``
    #: (``experiments.common.scenarios.held_out_scenarios``; not a benchmark)
    tests: Callable[[dict, bool], list]
    #: the classical laws that apply: ``mrd-env benchmark`` scores them (with ``benchmark_laws``,
    #: ``experiments.benchmark.run.shipped_controllers``), the reward-separation measurement compares them
    laws: tuple
    #: the controllers ``mrd-env benchmark`` scores besides ``laws`` (the building's clipped-optimal with each
    #: inverse model); the controllers' speed measurement times them
    benchmark_laws: tuple
    #: the laws drawn next to the agents' validation curves (``mrd-env train``): the best law at the agents' 10 ms
    #: and a passive one
    reference_laws: tuple
    #: ``response(scenario_options)``: the key response of an episode's history (a sensor, ``name[i]`` for channel
    #: i); the building's follows its damper's storey
    response: Callable[[dict], str]
    #: the model predictive control rows ``mrd-env benchmark`` scores (``experiments.benchmark.run.
    #: shipped_controllers``): (label, control step (None: any suite's), controller options, road preview); a
    #: row runs on a suite of its control step, a preview row only on a suite that grants the road-preview sensor
    mpc: tuple = ()
    #: ``passive_reference(scenario_options) -> (row name, environment options)``: the conventional passive plant of
    #: a set-up (the MR damper replaced by the set's passive damper; None: no such plant)
    passive_reference: Callable[[dict], tuple[str, dict]] | None = None
    #: the SI unit of each metric that has one (the score tables' headers, ``experiments.benchmark.scoring``;
    #: ratios have none)
    metric_units: dict = field(default_factory=dict)
    #: the road-preview sensor exists (``mrd-env train --preview``, ``experiments.common.scenarios.preview_options``)
    preview: bool = False
    #: laws whose commands warm-start the clairvoyant: of a suite's references (``mrd-env suite build``,
    #: ``experiments.benchmark.references``) and of the learning curves' yardstick (``experiments.benchmark.
    #: yardstick``); empty: neither can be computed on the plant
    warm_laws: tuple = ()
    #: why there is no yardstick (when ``warm_laws`` is empty; the yardstick's one-line refusal)
    no_yardstick: str = ""
    #: the environment id whose hyperparameter entry is used where the YAML file has none for ``env_id``
    #: (``experiments.training.trainers``)
    hyperparams_fallback: str | None = None
    #: one of the plants of ``--plant both`` (``experiments.common.plants.chosen_plants``: ``mrd-env benchmark``,
    #: the measurements), listed first under ``--plant all``
    published: bool = False
    #: the plant ``mrd-env train`` and ``mrd-env tune`` take without ``--plant`` (one plant says so)
    train_default: bool = False
    #: the plant's frozen benchmark suites (:class:`mrd_env.suites.SuiteDefinition`; their references ship in
    #: ``suites/`` of the plant's folder)
    suites: tuple = ()
    #: the plant's options the commands offer (:class:`PlantOption`; ``experiments.common.plants`` adds them)
    plant_options: tuple = ()
    #: ``apply_plant_options(environment options, {option name: text}) -> environment options``: the values of
    #: ``plant_options`` applied to a set of environment options (``ValueError`` naming the option and its valid
    #: values); it leaves the other options (the disturbance, the sensors) as they are
    apply_plant_options: Callable[[dict, dict], dict] | None = None
    #: the plant options this profile was derived with (:meth:`with_plant_options`): sorted (name, text) pairs
    applied: tuple = ()

    @property
    def name(self) -> str:
        """The plant's name (``--plant``)."""
        return self.spec.name

    @property
    def env_id(self) -> str:
        """The physics-level environment id (laws at 1 ms, commands in V or A)."""
        return self.spec.physics_id

    @property
    def title(self) -> str:
        return self.spec.title

    @property
    def offered_options(self) -> tuple:
        """The plant options the commands offer for this plant: its own and :data:`DAMPER_OPTION`."""
        return (*self.plant_options, DAMPER_OPTION)

    def with_plant_options(self, given: Mapping[str, str]) -> "PlantProfile":
        """This profile with plant options applied (``given``: {option name: text}; None values are not given) to
        its environment options and its training distribution; itself if none is given. ``ValueError`` for an
        option the plant does not offer or a bad value."""
        given = {k: v for k, v in given.items() if v is not None}
        if not given:
            return self
        self._check_offered(given)
        base = _registered(self.name)
        values = {**dict(self.applied), **given}
        return dataclasses.replace(base, options=self.plant_environment(base.options, values),
                                   training=self.plant_environment(base.training, values),
                                   applied=tuple(sorted(values.items())))

    def _check_offered(self, values: Mapping[str, str]) -> None:
        """``ValueError`` naming the first of ``values`` that is not one of this plant's options."""
        offered = [o.name for o in self.offered_options]
        unknown = [k for k in values if k not in offered]
        if unknown:
            raise ValueError(f"--{unknown[0]} is not an option of the {self.title} (its plant options: "
                             f"{', '.join('--' + o for o in offered)})")

    def plant_environment(self, options: Mapping, values: Mapping[str, str]) -> dict:
        """Environment ``options`` with the plant options ``values`` ({option name: text}) applied (``ValueError``
        for an option the plant does not offer)."""
        self._check_offered(values)
        out = dict(options)
        own = {k: v for k, v in values.items() if k != DAMPER_OPTION.name}
        if own:
            out = self.apply_plant_options(out, own)
        if DAMPER_OPTION.name in values:
            from ..dampers import damper_class

            damper = values[DAMPER_OPTION.name]
            try:
                damper_class(damper)
            except ValueError as exc:
                raise ValueError(f"--damper {damper}: {exc}") from None
            out["damper"] = damper
        return out

    def __reduce__(self):
        """A profile travels to a worker process (a process pool's, Ray's) as its plant's name (and the plant options
        it was derived with), and the worker takes the same profile from the registry: a profile holds functions,
        lambdas among them, that do not pickle."""
        if self.applied:
            return _derived, (self.name, dict(self.applied))
        if _registered(self.name) is not self:
            raise pickle.PicklingError(f"a profile of {self.name} that is not the registered one does not pickle")
        return _registered, (self.name,)


def _registered(name: str) -> PlantProfile:
    """The registered profile of plant ``name`` (:func:`mrd_env.plants.plant`)."""
    from . import plant

    return plant(name).profile


def _derived(name: str, applied: dict) -> PlantProfile:
    """The registered profile of plant ``name`` with the plant options ``applied``."""
    return _registered(name).with_plant_options(applied)
