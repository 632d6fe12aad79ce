"""The plants as the commands see them: every plant's profile (:class:`mrd_env.plants.profile.PlantProfile`,
declared in its folder), resolved once per command from a ``--plant`` value and passed down.

The commands read these profiles and never branch on a plant's name; a new plant reaches every command through its
folder and its line in :data:`mrd_env.plants.PLANT_FOLDERS`.
"""
from __future__ import annotations

import argparse
import reprlib
import warnings

from mrd_env.plants import plant, plant_of_id, plants
from mrd_env.plants.profile import PlantProfile, TestCase

__all__ = ["PlantProfile", "TestCase", "profiles", "profile", "by_env_id", "plant_choices", "plant_name",
           "default_plant", "chosen_plants", "add_plant_options", "with_plant_options",
           "check_suite_plant"]


def profiles() -> dict[str, PlantProfile]:
    """Every plant's profile by its name, in registry order (each imports its environment's module on first use)."""
    return {name: spec.profile for name, spec in plants().items()}


def profile(name: str | PlantProfile) -> PlantProfile:
    """The profile of plant ``name`` (a profile is returned as it is); ``ValueError`` naming the plants otherwise."""
    if isinstance(name, PlantProfile):
        return name
    return plant(name).profile


def by_env_id(env_id: str) -> PlantProfile | None:
    """The profile whose environment is ``env_id`` (None if none is)."""
    spec = plant_of_id(env_id)
    return None if spec is None else spec.profile


def plant_choices(both: bool = False) -> list[str]:
    """The values of a ``--plant`` option: every plant, and with ``both`` also "both" and "all" (a former name is
    taken too, :func:`plant_name`, but not offered)."""
    return sorted(plants()) + (["both", "all"] if both else [])


def plant_name(value: str) -> str:
    """A ``--plant`` value in today's spelling (argparse's ``type``, checked against :func:`plant_choices` after it):
    a former name, after its DeprecationWarning on stderr; anything else as it is."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", DeprecationWarning)  # Python hides it outside __main__: a command shows it
        try:
            return plant(value).name
        except ValueError:
            return value  # "both", "all", or a typo that argparse's choices name


def default_plant() -> str:
    """The ``--plant`` of the commands that take one plant (train, tune) when none is given: the plant whose profile
    says so (:attr:`PlantProfile.train_default`)."""
    chosen = [name for name, p in profiles().items() if p.train_default]
    if len(chosen) != 1:
        raise ValueError(f"exactly one plant profile must set train_default, got {chosen}")
    return chosen[0]


def chosen_plants(value: str) -> list[PlantProfile]:
    """The plants of a ``--plant`` value: "both" (the published benchmark's plants), "all" or one plant (a former
    name after a DeprecationWarning)."""
    every = profiles()
    published = [p for p in every.values() if p.published]
    if value == "both":
        return published
    if value == "all":
        return [*published, *(every[n] for n in sorted(every) if not every[n].published)]
    return [profile(value)]


def _dest(name: str) -> str:
    return "plant_option_" + name.replace("-", "_")


#: The longest plant option's text taken (characters): a command line's option, not a file.
MAX_OPTION_TEXT = 100_000


def _bounded(text) -> str:
    r = reprlib.Repr()
    r.maxstring = r.maxother = 80
    return r.repr(text)


def _text_problem(text: str, valid: str) -> str | None:
    """What is wrong with a plant option's text (None: nothing), naming ``valid``, its valid values."""
    if len(text) > MAX_OPTION_TEXT:
        why = f"{len(text)} characters, more than {MAX_OPTION_TEXT}"
    elif not (text.isascii() and text.isprintable()):
        why = "not plain ASCII"
    else:
        return None
    return f"takes {valid or 'plain ASCII text'}, got {_bounded(text)} ({why})"


def check_option_text(name: str, text, valid: str = "") -> str:
    """The text of plant option ``--name``, checked: printable ASCII (``'²'.isdigit()`` and ``'٣'.isdigit()`` are true,
    but neither is a digit the plants parse), at most :data:`MAX_OPTION_TEXT` characters; ``ValueError`` naming the
    option and ``valid`` (its valid values) otherwise."""
    text = str(text)
    problem = _text_problem(text, valid)
    if problem:
        raise ValueError(f"--{name} {problem}")
    return text


def _option_type(option):
    """argparse's ``type`` of a plant option (:func:`check_option_text`; argparse names the option)."""
    def parse(text: str) -> str:
        problem = _text_problem(text, f"{option.metavar}: {option.help}")
        if problem:
            raise argparse.ArgumentTypeError(problem)
        return text

    parse.__name__ = option.name.replace("-", "_")
    return parse


def add_plant_options(parser: argparse.ArgumentParser) -> None:
    """Every plant's options (:attr:`PlantProfile.offered_options`: the building's ``--storeys``, ...; ``--damper``
    of every plant where the command has no ``--damper`` of its own), each once; :func:`with_plant_options` applies
    them to the chosen plants."""
    group = parser.add_argument_group("plant options (they change the chosen plant; a plant without one refuses it)")
    seen = set(parser._option_string_actions)
    for p in profiles().values():
        for o in p.offered_options:
            if f"--{o.name}" in seen:
                continue
            seen.add(f"--{o.name}")
            group.add_argument(f"--{o.name}", dest=_dest(o.name), metavar=o.metavar, default=None, help=o.help,
                               type=_option_type(o))


def plant_option_values(args: argparse.Namespace) -> dict[str, str]:
    """{option name: text} of the plant options given on the command line (:func:`add_plant_options`'s)."""
    names = {o.name for p in profiles().values() for o in p.offered_options}
    return {n: getattr(args, _dest(n)) for n in sorted(names) if getattr(args, _dest(n), None) is not None}


def with_plant_options(plants: list[PlantProfile], args: argparse.Namespace) -> list[PlantProfile]:
    """The chosen ``plants`` with the plant options of the command line applied
    (:meth:`PlantProfile.with_plant_options`; ``ValueError`` for a plant that lacks one, or a bad value)."""
    given = _checked(plant_option_values(args))
    return [_naming(given, p.with_plant_options, given) for p in plants]


def _checked(given: dict) -> dict:
    """``given`` ({option: text}) with every text checked (:func:`check_option_text`): also for values set from
    Python, which argparse's type did not see."""
    return {k: check_option_text(k, v) for k, v in given.items()}


def _flags(given: dict) -> str:
    """The options as typed (each value cut to 80 characters)."""
    return " ".join(f"--{k} {v if len(v) <= 80 else v[:77] + '...'}" for k, v in given.items())


def _naming(given: dict, fn, *args):
    """``fn(*args)``, with a ``ValueError`` that names no option (a plant's int() of a value, say) prefixed by the
    options ``given``: every bad value's line names its option."""
    try:
        return fn(*args)
    except ValueError as exc:
        text = str(exc)
        if not any(f"--{k}" in text for k in given):
            raise ValueError(f"{_flags(given)}: {text}") from None
        raise


def _plain(value):
    """``value`` with tuples as lists (suite options and environment options compare by value)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def check_suite_plant(suite, args: argparse.Namespace) -> None:
    """A suite fixes its plant: plant options that would change it are refused (``ValueError`` naming the suites of
    that plant whose plant they describe); options that describe the suite's own plant pass."""
    given = _checked(plant_option_values(args))
    if not given:
        return
    plant = profile(suite.plant)
    if _plain(_naming(given, plant.plant_environment, suite.options, given)) == _plain(suite.options):
        return
    flags = _flags(given)
    fits = [f"{d.name}-v{d.version}" for d in plant.suites
            if _plain(_naming(given, plant.plant_environment, d.options, given)) == _plain(d.options)]
    raise ValueError(f"{flags} would change the plant of suite {suite.name}-v{suite.version}, and a suite fixes its "
                     f"plant; " + (f"score {' or '.join(fits)}, whose plant that is" if fits
                                   else "no shipped suite has that plant (make one: mrd-env suite build SPEC)"))
