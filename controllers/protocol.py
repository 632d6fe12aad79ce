"""What a controller must be to be scored on a benchmark suite (``mrd-env score``, :mod:`experiments.benchmark.scoring`):
the :class:`ControllerProtocol`, and how a user's ``module:attribute`` becomes one.

**What it is given.** A controller is built once per scenario of the suite from the environment it will drive — a
Gymnasium *vector* environment of that scenario's episodes (one row per episode), with the suite's options and
control step. From that environment it may read what the environment *declares*:

* ``sensor_layout`` (``(name, slice, unit)`` of each sensor in one measurement; with ``history`` > 1 the
  observation stacks measurements, oldest first: :func:`mrd_env.envs.sensors.newest_layout` gives the newest's
  slices), ``observation_labels``, ``single_observation_space``;
* ``roles`` (which sensor is the body velocity, the damper velocity, the damper stroke, ...: read signals by role,
  not by a plant's sensor names, and a controller serves every plant that declares those roles; every plant's roles:
  docs/your-controller.md, "The roles a controller reads");
* ``command_spec`` (the command's unit and range ``v_min``..``v_max``, V or A), ``n_dampers``, ``action_mode``,
  ``single_action_space``;
* ``control_dt`` (the step at which ``predict`` is called, s), ``dt`` (the physics step), ``preview_times``;
* ``linear_plant``, ``signal_matrices(name)``, ``output_matrices()`` (the plant's linear model and output maps),
  ``objective`` (its default control weights), ``F_static`` (the damper's static preload).

* ``num_envs`` (the rows of a batch), ``observation_space``, ``action_space``, ``sensors``, ``plant_kind``,
  ``plant_params``, ``damper`` (the damper model: its parameters and command channel), ``max_episode_steps``;
* ``assembly``, of which only the plant's declarations: ``kind``, ``damper``, ``plant_params``, ``linear_plant``,
  ``coupled`` (the plant coupled to its dampers: ``coupled.system``'s matrices), ``reward`` (its weights),
  ``filters``, ``options``, ``roles``, ``objective``, ``dt``, ``control_dt``, ``n_sub``, ``action_mode``,
  ``preview_times``, ``episode_seconds``, ``sensor_names``, ``nominal_reference`` (the plant's nominal disturbance's
  mean squares, not the episode's).

It cannot step, reset or read the state of the environment (its damper force, its disturbance, the road ahead): the
scorer hands it :func:`declarations` of the environment — a read-only view holding exactly the names above, each a
copy (changing it changes nothing in the environment) — and every other name (``step``, ``reset``, ``close``,
``call``, ``get_wrapper_attr``, ``unwrapped``, ``core``, ``assembly.disturbance``, ...) raises
:class:`DeclarationsOnly` (an ``AttributeError``, so ``getattr(env, "unwrapped", env)`` gives the view itself) naming
the name. During an episode a controller knows the plant through the observations ``predict`` receives, nothing
else (a preview sensor's road ahead is in the observation, where the suite gives one). The view is not a sandbox:
the controller's code runs in the scorer's process, and a result file is a claim made by the code that produced it,
as any benchmark figure is.

**What it must do.** ``predict(observation, state=None, episode_start=None, deterministic=True) -> (action, state)``
(Stable-Baselines3's signature), called once every ``control_dt`` with the observations of every episode at once,
``observation`` of shape ``(N, n_obs)`` (float32; the suite's sensors, noise, delay and history), and returning
``action`` of shape ``(N, n_dampers)`` (``(N,)`` is taken when there is one damper) in the environment's action space:
the command in V or A (``action_mode="physical"``), or mapped to [−1, 1] (``"normalized"``: −1 is ``v_min``, +1
``v_max``), as the suite's ``action_mode`` says (``env.single_action_space`` holds the bounds either way). An action
outside the space (by more than 10⁻⁶ of its range) stops the scoring with a one-line error naming the range, its unit
and the actions' min and max — a force in N or a [−1, 1] action on a 0–2 V suite is not clipped into a wrong score;
a law that can overshoot clips its own actions. A non-finite value or a wrong shape stops it too. ``state`` is returned to the next call (None for a memoryless law; a recurrent policy's
hidden state); ``episode_start`` is a boolean per row, True at the first step of that row's episode (the rows the
controller must forget). ``deterministic`` is always True.

``reset(mask=None)`` is optional: called (without a mask) before the first step of the scenario's episodes; a
controller with memory clears it there, or where ``episode_start`` is true.

**What the scorer accepts** as a controller (:func:`build_controller`): a class or a factory (any callable) taking the
environment (its :func:`declarations`) and returning an object with ``predict`` — the preferred form, so that the controller reads the
environment's declarations and fits every suite that declares what it needs — or an object that already has
``predict`` (built by the user beforehand: it is used as it is, for every scenario). Every law of
:mod:`controllers` is such a class (:class:`~controllers.base.Controller`), and a trained agent is scored through
``agent.bind(env)``.

**Importing user code.** ``mrd-env score --controller package.module:attribute`` imports ``package.module`` (from the
current folder or the installed packages) and runs whatever it runs on import: naming it on the command line is the
user's explicit decision to run that code, as ``python -m`` is. Nothing else ever imports code named by a file: a
suite file, an agent folder or a result file names no code that the project would import.
"""
from __future__ import annotations

import copy
import importlib
import inspect
import re
import reprlib
from typing import Any, Protocol, runtime_checkable

__all__ = ["ControllerProtocol", "DeclarationsOnly", "EnvironmentView", "build_controller", "declarations",
           "import_object", "is_import_spec"]

#: What a controller may read of the environment it is given (:func:`declarations`): its declarations, values.
ENV_DECLARATIONS = ("num_envs", "single_observation_space", "single_action_space", "observation_space",
                    "action_space", "sensor_layout", "observation_labels", "sensors", "roles", "command_spec",
                    "n_dampers", "action_mode", "control_dt", "dt", "preview_times", "linear_plant", "plant_kind",
                    "plant_params", "damper", "F_static", "objective", "max_episode_steps")
#: ... and its methods of declarations (the linear maps of its signals).
ENV_METHODS = ("signal_matrices", "output_matrices")
#: What a controller may read of ``env.assembly``: the plant's declarations, not its disturbance, episodes or
#: metrics.
ASSEMBLY_DECLARATIONS = ("kind", "damper", "plant_params", "linear_plant", "coupled", "reward", "filters", "options",
                         "roles", "objective", "dt", "control_dt", "n_sub", "action_mode", "preview_times",
                         "episode_seconds", "sensor_names", "nominal_reference")


def _bounded(value) -> str:
    """``repr(value)`` in at most about 120 characters (an error message's quote of what the user gave)."""
    r = reprlib.Repr()
    r.maxstring = r.maxother = r.maxlong = 120
    return r.repr(value)


class DeclarationsOnly(AttributeError):
    """A name of the environment that a controller may not use: stepping, resetting, closing, the state, the
    disturbance, the wrapped environment (:func:`declarations`)."""


def _refuse(what: str, name: str, allowed) -> DeclarationsOnly:
    shown = name if len(name) <= 60 else name[:57] + "..."
    return DeclarationsOnly(f"{what}.{shown} is refused: a controller sees the environment's declarations only "
                            f"(it may read {', '.join(allowed)}), never steps, resets or reads its state or "
                            "disturbance")


class EnvironmentView:
    """The environment as a controller sees it (:func:`declarations`): the declarations of
    :data:`ENV_DECLARATIONS` and :data:`ENV_METHODS` (``assembly``: :data:`ASSEMBLY_DECLARATIONS`), each a copy, read
    only; any other name raises :class:`DeclarationsOnly`. The environment itself is held in a closure, not in an
    attribute."""

    __slots__ = ("_read",)
    _what = "env"
    _allowed = (*ENV_DECLARATIONS, *ENV_METHODS, "assembly")

    def __init__(self, read):
        object.__setattr__(self, "_read", read)

    def __getattr__(self, name: str):  # only names the class does not define come here
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)  # copy, pickle and numpy probe dunders: plain absence
        if name not in self._allowed:
            raise _refuse(self._what, name, self._allowed)
        return self._read(name)

    def __setattr__(self, name: str, value) -> None:
        raise DeclarationsOnly(f"{self._what} is read-only for a controller: setting {name[:60]!r} is refused")

    def __delattr__(self, name: str) -> None:
        raise DeclarationsOnly(f"{self._what} is read-only for a controller: deleting {name[:60]!r} is refused")

    def __dir__(self):
        return sorted(self._allowed)

    def __copy__(self):
        return self  # read-only: a copy is the same view

    def __deepcopy__(self, memo):
        return self

    def __repr__(self) -> str:
        return f"<the declarations of an environment: {', '.join(self._allowed)}>"


class _AssemblyView(EnvironmentView):
    """``env.assembly`` as a controller sees it: the plant's declarations only."""

    __slots__ = ()
    _what = "env.assembly"
    _allowed = ASSEMBLY_DECLARATIONS


def declarations(env) -> EnvironmentView:
    """A read-only view of ``env`` (scalar or vector) for a controller: what it declares, never its state (see the
    module docstring). Values are copied once per view (shared between the view and its ``assembly``, so that
    ``env.command_spec`` is ``env.damper.command``); a method's result is a fresh copy per call; a view is returned
    as it is."""
    if isinstance(env, EnvironmentView):
        return env
    memo: dict = {}
    cache: dict = {}

    def value(obj, key, name):
        if key not in cache:
            raw = getattr(obj, name)
            # the nominal reference is the plant's function (of its nominal disturbance): shared, not copied
            cache[key] = raw if name == "nominal_reference" else copy.deepcopy(raw, memo)
        return cache[key]

    def read_assembly(name):
        return value(env.assembly, ("assembly", name), name)

    def read(name):
        if name in ENV_METHODS:
            method = getattr(env, name)

            def call(*args, **kwargs):
                return copy.deepcopy(method(*args, **kwargs))

            call.__name__ = call.__qualname__ = name
            call.__doc__ = method.__doc__
            return call
        if name == "assembly":
            if not hasattr(env, "assembly"):
                raise AttributeError(f"the environment ({type(env).__name__}) declares no assembly")
            if "assembly" not in cache:
                cache["assembly"] = _AssemblyView(read_assembly)
            return cache["assembly"]
        return value(env, name, name)

    return EnvironmentView(read)

#: ``package.module:attribute`` (the attribute may be dotted: ``module:Class.factory``).
_SPEC = re.compile(r"[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*")


@runtime_checkable
class ControllerProtocol(Protocol):
    """A controller as the scorer drives it (see the module docstring for what it may read and must return):
    ``predict(observation (N, n_obs), state, episode_start (N,), deterministic=True) -> (action (N, n_dampers),
    state)``, and optionally ``reset(mask=None)``. ``isinstance(obj, ControllerProtocol)`` checks that ``predict``
    exists (not its signature)."""

    def predict(self, observation, state: Any = None, episode_start=None,
                deterministic: bool = True) -> tuple[Any, Any]:
        ...


def is_import_spec(text: str) -> bool:
    """Whether ``text`` has the form ``package.module:attribute``."""
    return isinstance(text, str) and _SPEC.fullmatch(text) is not None


def import_object(spec: str) -> Any:
    """The object ``package.module:attribute`` names, after importing ``package.module`` — **this runs the module's
    code** (the caller's explicit choice: see the module docstring). ``ValueError`` with one line for a malformed
    name, a module that cannot be imported (whatever its import raised) or a missing attribute."""
    if not is_import_spec(spec):
        raise ValueError(f"{_bounded(spec)} is not of the form package.module:attribute")
    module_name, _, attr = spec.partition(":")
    try:
        obj = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and (module_name == exc.name or module_name.startswith(exc.name + ".")):
            raise ValueError(f"{spec}: no module named {exc.name!r} (on the current folder or the installed "
                             "packages)") from None
        raise ValueError(f"{spec}: importing {module_name} failed: {type(exc).__name__}: {exc}") from exc
    except Exception as exc:  # the user's module raised on import (SyntaxError included): their problem, one line
        raise ValueError(f"{spec}: importing {module_name} failed: {type(exc).__name__}: {exc}") from exc
    except SystemExit as exc:  # sys.exit() on import: the module's doing (no signal raises SystemExit here)
        raise ValueError(f"{spec}: importing {module_name} raised SystemExit({_bounded(exc.code)}): a controller's "
                         "module must not exit") from None
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"{spec}: {module_name} has no attribute {attr!r}") from None
    return obj


def build_controller(obj: Any, env, what: str = "controller") -> ControllerProtocol:
    """The controller ``obj`` makes for ``env``: a class or factory is called with :func:`declarations` of ``env``;
    an object with ``predict`` is returned as it is. ``ValueError`` (one line naming ``what``) when ``obj`` is
    neither, when the factory raises, or when what it returns has no ``predict``."""
    if not inspect.isclass(obj) and isinstance(obj, ControllerProtocol):
        return obj
    env = declarations(env)
    if not callable(obj):
        raise ValueError(f"{what}: a {type(obj).__name__} is neither a controller (an object with predict) nor a "
                         "class or factory taking the environment")
    try:
        ctrl = obj(env)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from exc
    except Exception as exc:  # the user's factory: its error, on one line
        raise ValueError(f"{what}: building it on the suite's environment raised {type(exc).__name__}: {exc}") \
            from exc
    if not isinstance(ctrl, ControllerProtocol):
        raise ValueError(f"{what}: called with the environment it returned a {type(ctrl).__name__}, which has no "
                         "predict(observation, state, episode_start, deterministic) method")
    return ctrl
