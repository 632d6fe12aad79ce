"""What the experiments know about a plant (:class:`PlantProfile`): its environment options, what agents train on,
the held-out test scenarios, the laws that apply, the metrics and the figures' layout. Each plant declares its
profile in its folder (``mrd_env/plants/<plant>/profile.py``: ``PROFILE``); the commands (``train``,
``evaluate``, ``benchmark``, ``tune``, ``yardstick``, the labs) read it and never branch on a plant's name.

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
    #: environment options every experiment gives the plant (training, validation, test, benchmark)
    options: dict
    #: the training distribution as environment options (a new disturbance per episode)
    training: dict
    #: the environment option holding the disturbance ("road", "ground_motion")
    disturbance_key: str
    #: ``tests(plant_options, quick) -> [TestCase]``: the held-out test scenarios on ``plant_options``
    tests: Callable[[dict, bool], list]
    #: the classical laws ``mrd-env evaluate`` compares (by default)
    laws: tuple
    #: the controllers ``mrd-env benchmark`` runs (by default)
    benchmark_laws: tuple
    #: the laws drawn next to the agents' validation curves: the best law at the agents' 10 ms and a passive one
    reference_laws: tuple
    #: the metric columns of ``mrd-env evaluate``
    evaluation_metrics: tuple
    #: the metric columns of ``mrd-env benchmark``
    benchmark_metrics: tuple
    #: ``response(scenario_options)``: the key response of the histories (a sensor, ``name[i]`` for channel i)
    response: Callable[[dict], str]
    #: the histories' y label of a response and the factor from SI to the label's unit
    response_axis: Callable[[str], tuple[str, float]]
    #: benchmark metrics also divided by passive-off's on the same episode (``<metric>/off`` columns)
    normalise_by_passive_off: bool = False
    #: the bar chart's ratios (benchmark: worst case over the scenarios) and its y label
    bar_metrics: tuple = ()
    bar_ylabel: str = "ratio to passive-off (dimensionless)"
    bar_legend_columns: int = 4
    #: model predictive control rows of ``mrd-env evaluate``: (label, control step (None: the comparison's),
    #: controller options, road preview)
    mpc: tuple = ()
    #: ``passive_reference(scenario_options) -> (row name, environment options)``: the conventional passive plant the
    #: benchmark adds as a row (the MR damper replaced by the set-up's passive damper; None: no such row)
    passive_reference: Callable[[dict], tuple[str, dict]] | None = None
    #: the SI unit of each metric column that has one (the tables' headers; ratios have none)
    metric_units: dict = field(default_factory=dict)
    #: the road-preview sensor exists (``--preview``; the MPC preview rows)
    preview: bool = False
    #: laws whose commands warm-start the clairvoyant of ``mrd-env yardstick`` (empty: no yardstick)
    warm_laws: tuple = ()
    #: why there is no yardstick (when ``warm_laws`` is empty)
    no_yardstick: str = ""
    #: the environment id whose hyperparameter entry is used where the YAML file has none for ``env_id``
    hyperparams_fallback: str | None = None
    #: one of the plants of the published benchmark, evaluation and yardstick (``--plant both``)
    published: bool = False
    #: the plant ``mrd-env train`` and ``mrd-env tune`` take without ``--plant`` (one plant says so)
    train_default: bool = False
    extra: dict = field(default_factory=dict)
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
    #: the environment options that make the plant (the building's preset and damper storeys): an agent trained on
    #: other values is refused where the command runs this plant (the damper has its own rule, ``--damper``)
    plant_keys: tuple = ()

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
