"""What a controller must be to be scored on a benchmark suite (``mrd-env score``, :mod:`experiments.common.scoring`):
the :class:`ControllerProtocol`, and how a user's ``module:attribute`` becomes one.

**What it is given.** A controller is built once per scenario of the suite from the environment it will drive — a
Gymnasium *vector* environment of that scenario's episodes (one row per episode), with the suite's options and
control step. From that environment it may read what the environment *declares*:

* ``sensor_layout`` (``(name, slice, unit)`` of each sensor in one measurement; with ``history`` > 1 the
  observation stacks measurements, oldest first: :func:`mrd_env.envs.sensors.newest_layout` gives the newest's
  slices), ``observation_labels``, ``single_observation_space``;
* ``roles`` (which sensor is the body velocity, the damper velocity, the damper stroke, ...: read signals by role,
  not by a plant's sensor names, and a controller serves every plant that declares those roles);
* ``command_spec`` (the command's unit and range ``v_min``..``v_max``, V or A), ``n_dampers``, ``action_mode``,
  ``single_action_space``;
* ``control_dt`` (the step at which ``predict`` is called, s), ``dt`` (the physics step), ``preview_times``;
* ``linear_plant``, ``signal_matrices(name)``, ``output_matrices()`` (the plant's linear model and output maps),
  ``objective`` (its default control weights), ``F_static`` (the damper's static preload).

It must not step, reset or read the state of the environment (its damper force, its disturbance, the road ahead):
during an episode it knows the plant through the observations ``predict`` receives, nothing else. The scorer does
not sandbox this — a result file is a claim made by the code that produced it, as any benchmark figure is.

**What it must do.** ``predict(observation, state=None, episode_start=None, deterministic=True) -> (action, state)``
(Stable-Baselines3's signature), called once every ``control_dt`` with the observations of every episode at once,
``observation`` of shape ``(N, n_obs)`` (float32; the suite's sensors, noise, delay and history), and returning
``action`` of shape ``(N, n_dampers)`` (``(N,)`` is taken when there is one damper) in the environment's action space:
the command in V or A (``action_mode="physical"``), or mapped to [−1, 1] (``"normalized"``: −1 is ``v_min``, +1
``v_max``), as the suite's ``action_mode`` says (``env.single_action_space`` holds the bounds either way). Values
outside the space are clipped, as the environment clips them; a non-finite value or a wrong shape stops the scoring
with a one-line error. ``state`` is returned to the next call (None for a memoryless law; a recurrent policy's
hidden state); ``episode_start`` is a boolean per row, True at the first step of that row's episode (the rows the
controller must forget). ``deterministic`` is always True.

``reset(mask=None)`` is optional: called (without a mask) before the first step of the scenario's episodes; a
controller with memory clears it there, or where ``episode_start`` is true.

**What the scorer accepts** as a controller (:func:`build_controller`): a class or a factory (any callable) taking the
environment and returning an object with ``predict`` — the preferred form, so that the controller reads the
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

import importlib
import inspect
import re
from typing import Any, Protocol, runtime_checkable

__all__ = ["ControllerProtocol", "build_controller", "import_object", "is_import_spec"]

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
        raise ValueError(f"{spec!r} is not of the form package.module:attribute")
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
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"{spec}: {module_name} has no attribute {attr!r}") from None
    return obj


def build_controller(obj: Any, env, what: str = "controller") -> ControllerProtocol:
    """The controller ``obj`` makes for ``env``: a class or factory is called with ``env``; an object with
    ``predict`` is returned as it is. ``ValueError`` (one line naming ``what``) when ``obj`` is neither, when the
    factory raises, or when what it returns has no ``predict``."""
    if not inspect.isclass(obj) and isinstance(obj, ControllerProtocol):
        return obj
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
