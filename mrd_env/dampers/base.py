"""The damper interface shared by every model.

A damper model is four things:

* a frozen parameter dataclass (SI units, validated on construction),
* internal states ``s`` advanced by ``rhs(p, s, x, xd, u, ds)`` (``ds`` = ds/dt),
* a force law ``force_law(p, s, x, xd, xdd, u) -> F`` (N, positive when resisting extension ``x``),
* the command dynamics from the commanded current/voltage ``v`` to the effective one ``u``: a pure delay and
  a first-order lag u̇ = −η (u − v), faster on a rise than on a fall if declared so (:class:`CommandSpec`,
  :mod:`mrd_env.command_lag`), common to all models and integrated exactly by the stepping routine.

``rhs``, ``force_law`` and ``project(p, s, x, xd, u)`` are numba ``@njit`` functions taking the parameter
vector ``p`` (``Params.as_array()``, fields in declaration order); ``project`` runs between integration
steps: it keeps the states in their invariant set (e.g. a Bouc–Wen z inside its saturation bound) and
switches discrete modes (:mod:`.acceleration_branch`). A model may add its analytic derivatives
``partials(p, s, x, xd, xdd, u, J, work)``, writing into J (ns + 1, ns + 2) the Jacobian of (ṡ, F) with respect
to (s, x, ẋ) — rows 0..ns−1 for ṡ, row ns for F; columns 0..ns−1 for s, then x, then ẋ; without them the
stepping routine differentiates ``rhs`` and ``force_law`` numerically (a test checks every analytic set
against finite differences). To evaluate a configured damper's force from Python,
call ``damper.force(x, v, u)``. Adding a model is one new module in this package that defines a
``DamperModel`` subclass decorated with ``@register``.
"""
from __future__ import annotations

import dataclasses
import math
import reprlib
from dataclasses import dataclass, field, fields
from typing import Any, Callable, ClassVar, Mapping

import numba as nb
import numpy as np

from ..validation import as_real, check_scalar, describe_range


# Why a parameter is kept fixed by identification unless named free (``param(..., fixed=...)``).
FIXED_SHAPE = "Bouc–Wen exponent: a shape choice, kept fixed (n = 2 in the presets)"
FIXED_SCALING = ("Bouc–Wen scaling redundancy: (α, A, β, γ) → (α/s, s·A, β/sⁿ, γ/sⁿ) gives the same force, so one "
                 "of them is fixed")
FIXED_SMOOTHING = "smoothing scale of a sign function: a numerical regularisation, not a damper property"
FIXED_FILTER = "time constant of an internal velocity filter: an estimator setting, not a damper property"
FIXED_TEST_CONDITION = "a condition of the test (set it to the record's value), not a damper property"


def param(default: float = dataclasses.MISSING, *, unit: str, lo: float = -math.inf, hi: float = math.inf,
          lo_open: bool = False, doc: str = "", fixed: str = "") -> Any:
    """Declare a model parameter: its SI ``unit``, valid range and meaning; ``fixed`` says why identification keeps
    it fixed by default (one of the ``FIXED_*`` reasons; empty: fitted by default)."""
    meta = {"unit": unit, "lo": lo, "hi": hi, "lo_open": lo_open, "doc": doc, "fixed": fixed}
    if default is dataclasses.MISSING:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class DamperParams:
    """Base of every model's parameters: checks each field against its declared range."""

    def __post_init__(self) -> None:
        for f in fields(self):
            m = f.metadata
            v = getattr(self, f.name)
            fv = as_real(f"{type(self).__name__}.{f.name}", v)
            lo_ok = fv > m["lo"] if m["lo_open"] else fv >= m["lo"]
            if not (math.isfinite(fv) and lo_ok and fv <= m["hi"]):
                raise ValueError(
                    f"{type(self).__name__}.{f.name} = {reprlib.repr(v)} is invalid: must be "
                    f"{describe_range(m['lo'], m['hi'], m['lo_open'], False, m['unit'])}")
            object.__setattr__(self, f.name, fv)
        self.check()

    def check(self) -> None:
        """Cross-field constraints (override); raise ``ValueError`` naming the fields."""

    def as_array(self) -> np.ndarray:
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=np.float64)

    def to_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @classmethod
    def units(cls) -> dict[str, str]:
        return {f.name: f.metadata["unit"] for f in fields(cls)}

    @classmethod
    def index_constants(cls) -> str:
        """The source line naming each parameter's index in ``p`` (``P_<NAME> = i`` in field order), as every
        model module declares it so that force laws read ``p[P_C0A]`` instead of ``p[0]``; a test checks each
        module's constants against this."""
        names = ", ".join(f"P_{n.upper()}" for n in cls.names())
        return f"{names} = range({len(cls.names())})"

    @classmethod
    def fixed_by_default(cls) -> dict[str, str]:
        """{name: reason} of the parameters that identification keeps fixed unless named free."""
        return {f.name: f.metadata["fixed"] for f in fields(cls) if f.metadata.get("fixed")}

    @classmethod
    def bounds(cls) -> dict[str, tuple[float, float]]:
        return {f.name: (f.metadata["lo"], f.metadata["hi"]) for f in fields(cls)}

    def replace(self, **changes: float) -> "DamperParams":
        unknown = set(changes) - set(self.names())
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for {type(self).__name__}; "
                             f"valid: {list(self.names())}")
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class CommandSpec:
    """The command channel: unit ('V' or 'A'), admissible range and the command dynamics
    (:mod:`mrd_env.command_lag`).

    u̇ = −η (u − v(t − τ)) with η = ``eta`` (1/s) while the command rises above u and ``eta_fall`` while it
    falls below (``None``: the same rate both ways), and a pure delay τ = ``delay`` (s): ``u`` reaches 63.2 %
    of a step in v after τ + 1/η seconds.
    """

    unit: str = "V"
    v_min: float = 0.0
    v_max: float = 1.0
    eta: float = 190.0
    eta_fall: float | None = None
    delay: float = 0.0

    def __post_init__(self) -> None:
        if self.unit not in ("V", "A"):
            raise ValueError(f"CommandSpec.unit must be 'V' or 'A', got {self.unit!r}")
        object.__setattr__(self, "v_min", check_scalar("CommandSpec.v_min", self.v_min, unit=self.unit))
        object.__setattr__(self, "v_max", check_scalar("CommandSpec.v_max", self.v_max, unit=self.unit))
        if not self.v_max > self.v_min:  # a pair: name both, whichever of them the caller changed
            raise ValueError(f"CommandSpec.v_max = {self.v_max:g} must be > CommandSpec.v_min = {self.v_min:g} "
                             f"{self.unit}")
        object.__setattr__(self, "eta", check_scalar("CommandSpec.eta", self.eta, 0.0, lo_open=True, unit="1/s"))
        if self.eta_fall is not None:
            object.__setattr__(self, "eta_fall", check_scalar("CommandSpec.eta_fall", self.eta_fall, 0.0,
                                                              lo_open=True, unit="1/s"))
        object.__setattr__(self, "delay", check_scalar("CommandSpec.delay", self.delay, 0.0, 1.0, unit="s"))

    @property
    def eta_down(self) -> float:
        """The lag rate of a falling command (1/s): ``eta_fall``, or ``eta`` when the lag is symmetric."""
        return self.eta if self.eta_fall is None else self.eta_fall

    def lag_vector(self) -> np.ndarray:
        """(η_rise, η_fall, τ) as the kernels take them (:data:`mrd_env.command_lag.LAG_RISE` ...)."""
        return np.array([self.eta, self.eta_down, self.delay])

    def check_command(self, v: np.ndarray | float, name: str = "command") -> np.ndarray:
        """Raise ``ValueError`` if any command is non-finite or outside [v_min, v_max]."""
        a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} contains a non-finite value")
        tol = 1e-12 * max(1.0, abs(self.v_max))
        if a.size and (a.min() < self.v_min - tol or a.max() > self.v_max + tol):
            raise ValueError(f"{name} must stay within [{self.v_min:g}, {self.v_max:g}] {self.unit} "
                             f"(the preset's range), got values in [{a.min():g}, {a.max():g}]")
        return a



#: The command channel of the Spencer et al. (1997) prototype damper, shared by every model's ``spencer1997``
#: preset: 0–2.25 V into the current driver, first-order lag η = 190 1/s, no delay.
PROTOTYPE_COMMAND = CommandSpec("V", 0.0, 2.25, 190.0)
#: The command channel of the automotive presets (``spencer_dyke`` and ``bouc_wen``): 0–2 V, η = 190 1/s.
AUTOMOTIVE_COMMAND = CommandSpec("V", 0.0, 2.0, 190.0)


def command_spec(command, base: CommandSpec) -> CommandSpec:
    """``command`` as a :class:`CommandSpec`: None → ``base``; a CommandSpec; or a dict of field overrides of
    ``base`` (``unit``, ``v_min``, ``v_max``, ``eta``, ``eta_fall``, ``delay``). Anything else raises ``ValueError``."""
    if command is None:
        return base
    if isinstance(command, CommandSpec):
        return command
    if isinstance(command, Mapping):
        valid = [f.name for f in fields(CommandSpec)]
        unknown = sorted(set(command) - set(valid), key=repr)  # keys of any type, e.g. an int
        if unknown:
            raise ValueError(f"command has unknown key(s) {unknown}; valid keys: {valid}")
        return dataclasses.replace(base, **command)
    raise ValueError(f"command must be a CommandSpec or a dict of its fields {[f.name for f in fields(CommandSpec)]}, "
                     f"got {type(command).__name__}")


@dataclass(frozen=True)
class Preset:
    """Published (or derived) parameters with their command channel and source."""

    params: DamperParams
    command: CommandSpec
    source: str
    verified: bool = True


class DamperModel:
    """A configured damper: a model class with its parameters and command channel.

    Subclasses set ``name``, ``Params``, ``state_names``, ``presets``, ``default_preset`` and the numba
    functions ``rhs``, ``force_law`` and ``project`` (see the module docstring).
    """

    name: ClassVar[str]
    Params: ClassVar[type[DamperParams]]
    state_names: ClassVar[tuple[str, ...]] = ()
    presets: ClassVar[dict[str, Preset]] = {}
    default_preset: ClassVar[str]
    rhs: ClassVar[Callable]
    force_law: ClassVar[Callable]
    project: ClassVar[Callable]
    partials: ClassVar[Callable | None] = None
    #: (project, force_law) as plain Python while the model's kernel runs interpreted on a first use (set by
    #: :mod:`mrd_env.stepping.first_use`), so that :meth:`force` compiles nothing then; else None.
    python_functions: ClassVar[tuple[Callable, Callable] | None] = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        # the compiled functions are plain functions of (p, s, ...): reachable from instances too
        for name in ("rhs", "force_law", "project", "partials"):
            f = cls.__dict__.get(name)
            if f is not None and not isinstance(f, staticmethod):
                setattr(cls, name, staticmethod(f))

    def __init__(self, params: DamperParams | None = None, command: CommandSpec | None = None,
                 preset: str | None = None):
        base = self.preset(preset)
        if params is not None and not isinstance(params, self.Params):
            raise ValueError(f"params for {self.name!r} must be a {self.Params.__name__}, "
                             f"got {type(params).__name__}")
        self.params = params if params is not None else base.params
        self.command = command_spec(command, base.command)

    @classmethod
    def preset(cls, name: str | None = None) -> Preset:
        key = cls.default_preset if name is None else name
        if not isinstance(key, str) or key not in cls.presets:
            raise ValueError(f"unknown preset {key!r} for damper model {cls.name!r}; "
                             f"available: {sorted(cls.presets)}")
        return cls.presets[key]

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    def initial_state(self) -> np.ndarray:
        """Internal states at rest (override when rest is not all zeros)."""
        return np.zeros(self.n_states)

    def rest_state(self, x: float) -> np.ndarray:
        """Internal states at rest at stroke ``x`` (m) with zero stroke rate: ``rhs`` gives ṡ = 0 there at every
        command. Where the model's rest states form a family (a Bouc–Wen z is at rest at any value when ẋ = 0, and
        which one a stroke leaves depends on its path), the one with the hysteresis variables at zero, as
        :meth:`initial_state`. Override when that depends on ``x`` (Spencer–Dyke: y = x)."""
        check_scalar("x", x, unit="m")
        return self.initial_state()

    def rest_states(self, strokes) -> np.ndarray:
        """:meth:`rest_state` of one damper at each stroke (m), concatenated (the layout of a plant's damper
        states)."""
        xs = np.atleast_1d(np.asarray(strokes, dtype=float))
        return np.concatenate([self.rest_state(float(x)) for x in xs]) if xs.size else np.zeros(0)

    def rest_force(self, x: float, u: float) -> float:
        """The force (N) at rest at stroke ``x`` (m): the internal states at :meth:`rest_state`, zero stroke rate,
        effective command ``u``; its difference from F at x = 0 is the damper's static stiffness force (e.g. a
        Spencer–Dyke accumulator's k1·x), which a plant's static equilibrium must hold."""
        return float(self.force(x, 0.0, u, state=self.rest_state(x)))

    def force(self, x, v, u, *, a=0.0, state=None):
        """The damper force (N) at stroke ``x`` (m), velocity ``v`` (m/s) and effective command ``u`` (V or A).

        ``state``: the internal states (``state_names``); by default the rest state, switched to the motion
        given (``project``), i.e. the force at the first instant of that motion from rest. ``a`` (m/s²) is
        the acceleration, used by the models with an inertance term. Scalars give a float; arrays broadcast
        to an array of forces.
        """
        from ..validation import check_array

        given_ = [check_array(name, val) for name, val in (("x", x), ("v", v), ("a", a), ("u", u))]
        try:
            xb, vb, ab, ub = np.broadcast_arrays(*given_)
        except ValueError:
            raise ValueError(f"x, v, a and u must broadcast to one shape, got shapes "
                             f"{', '.join(str(g.shape) for g in given_)}") from None
        self.command.check_command(ub, "u")
        p = self.params.as_array()
        given = None if state is None else check_array("state", state, shape=(self.n_states,))
        out = np.empty(xb.shape)
        project, force_law = type(self).python_functions or (self.project, self.force_law)
        with np.errstate(all="ignore"):  # the Python functions warn where the compiled ones do not; checked below
            for i in np.ndindex(xb.shape):
                s = self.initial_state() if given is None else given.copy()
                if given is None:
                    project(p, s, float(xb[i]), float(vb[i]), float(ub[i]))
                out[i] = force_law(p, s, float(xb[i]), float(vb[i]), float(ab[i]), float(ub[i]))
                if not math.isfinite(out[i]):  # float64 overflow: huge inputs or parameters, never a silent inf/NaN
                    raise ValueError(f"the force of {self.name!r} is not finite at x = {xb[i]:g} m, v = {vb[i]:g} "
                                     f"m/s, a = {ab[i]:g} m/s², u = {ub[i]:g} {self.command.unit}: the inputs or the "
                                     "parameters overflow float64")
        return float(out) if out.ndim == 0 else out

    def inertance(self) -> float:
        """Mass-like coefficient m of a force term m·ẍ (kg); plants add it to their mass matrix."""
        return 0.0

    def with_params(self, **changes: float) -> "DamperModel":
        return type(self)(self.params.replace(**changes), self.command)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.params!r}, {self.command!r})"


@nb.njit(cache=True)
def no_states_rhs(p, s, x, xd, u, ds):  # pragma: no cover - compiled
    """For memoryless force laws: there are no internal states to advance."""
    return


@nb.njit(cache=True)
def no_projection(p, s, x, xd, u):  # pragma: no cover - compiled
    return


@nb.njit(cache=True)
def smooth_sign(v, v_s):
    """sgn(v) smoothed over the velocity scale v_s (m/s): tanh(v / v_s); exact sign when v_s = 0."""
    if v_s <= 0.0:
        return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    return math.tanh(v / v_s)
