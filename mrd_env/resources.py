"""Memory budgets: what an option combination will allocate, estimated and checked before the work starts.

Every documented option that scales memory — ``episode_seconds``, ``dt``, a ground motion's ``time_scale``, a
road's ``duration`` or a measured profile's length, ``preview`` and the sensors (the columns of every row),
``num_envs`` of the vector environment, the length and count of a rig test, the number of dampers and storeys
(the plant's matrices, the kernel's constants and scratch, which grow with their square), a road's speed where
the road's length grows with 1/speed (the rear wheels' delay wheelbase/speed of the half and full car's roads) —
is turned into an estimate of the arrays it makes (the input records, the environment's input buffer, the history
the scalar environment keeps for ``signal()`` and rendering, the plant's per-episode data such as the building's
uncontrolled response, and the transient arrays of generating a record, FFT grids included). A file named by an
option is read only up to :func:`file_limit` bytes (:func:`mrd_env.storage.read_limited`). An estimate above the limit is refused with a ``ValueError`` naming the
option(s), the estimate and the limit, before anything is allocated; nothing is changed by a refusal.

The limit is :data:`ENV_VAR` (``MRD_ENV_MEMORY_LIMIT``) where set — a size such as ``8G``, ``512M``, ``2.5GiB``
or a number of bytes; ``none`` turns the check off — else :data:`DEFAULT_LIMIT` (4 GiB) or half the machine's
physical memory if that is less. It is read at every check, so a process may change it between two
environments.

The estimates are "about": within a factor of about 1.5 of what the arrays take (``tests/test_resources.py``
measures them), which is what a limit needs to tell a mistyped option from a long run.
"""
from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass

ENV_VAR = "MRD_ENV_MEMORY_LIMIT"
GIB = 1024 ** 3
#: The limit where ``MRD_ENV_MEMORY_LIMIT`` is not set (or half the physical memory, if that is less).
DEFAULT_LIMIT = 4 * GIB
FLOAT = 8  # bytes of a float64
#: Bytes per sample while a random record is generated (ISO 8608 road by FFT, Kanai–Tajimi filtered noise):
#: the spectrum, the noise, the filter outputs and the record itself (measured: 65–140).
GENERATED_SAMPLE_BYTES = 160

#: Bytes per sample of an FFT grid while a road is generated on it (the spectrum's lines, their amplitudes and
#: phases, the complex half-spectrum and the inverse transform's output; measured 17 with tracemalloc, 24–33
#: with the FFT's own buffers in the resident memory: ``experiments/measurements/memory/estimate.py``).
FFT_SAMPLE_BYTES = 32
#: Bytes of memory per byte of a text file while it is parsed into numbers (the text, its lines, the rows of
#: Python floats and the array: measured 10–14 on CSV and AT2 files): the file-size cap is the limit over this.
TEXT_FILE_EXPANSION = 16
#: The file-size cap when no memory limit is set (``MRD_ENV_MEMORY_LIMIT=none``).
UNLIMITED_FILE = 1 << 40

_UNITS = {"": 1, "b": 1, "k": 1024, "m": 1024 ** 2, "g": 1024 ** 3, "t": 1024 ** 4}


def parse_size(text: str) -> int | None:
    """A size as ``MRD_ENV_MEMORY_LIMIT`` holds it: bytes (``2147483648``, ``2e9``) or with a binary unit
    (``512M``, ``2G``, ``2GiB``, ``1.5 GB``: K, M, G, T are powers of 1024); ``none``/``off``: no limit (None).
    ``ValueError`` naming the variable otherwise."""
    s = str(text).strip().lower()
    if s in ("none", "off", "unlimited", "inf"):
        return None
    m = re.fullmatch(r"([0-9]*\.?[0-9]+(?:e[+-]?[0-9]+)?)\s*([kmgt]?)(?:i?b)?", s)
    if m is None or float(m.group(1)) <= 0 or not math.isfinite(float(m.group(1))):
        raise ValueError(f"{ENV_VAR}={text!r} is not a size: give bytes or a size with a unit (e.g. 8G, 512M, "
                         "2.5GiB), or 'none' for no limit")
    return int(float(m.group(1)) * _UNITS[m.group(2)])


def physical_memory() -> int | None:
    """The machine's physical memory in bytes (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def memory_limit() -> int | None:
    """The limit in bytes (see the module docstring); None: no limit."""
    given = os.environ.get(ENV_VAR, "").strip()
    if given:
        return parse_size(given)
    phys = physical_memory()
    return DEFAULT_LIMIT if not phys else min(DEFAULT_LIMIT, phys // 2)


def file_limit() -> int:
    """The most bytes a text file named by an option (a road profile, a ground-motion record, a damper record) may
    hold: the memory limit over :data:`TEXT_FILE_EXPANSION`, what parsing it takes (256 MiB under the default 4 GiB)."""
    limit = memory_limit()
    return UNLIMITED_FILE if limit is None else max(1 << 20, limit // TEXT_FILE_EXPANSION)


def format_bytes(n: float) -> str:
    """``n`` bytes in binary units, two significant digits ("4.5 GiB", "120 MiB")."""
    for unit, size in (("TiB", 1024 ** 4), ("GiB", GIB), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if n >= size:
            v = n / size
            return f"{v:.2g} {unit}" if v < 10 else f"{v:.0f} {unit}"
    return f"{n:.0f} B"


def samples_text(n: float, dt: float | None = None) -> str:
    """"100 000 001 samples at 1 kHz": a count with thin groups and the rate."""
    count = f"{int(n):,}".replace(",", " ") if n < 1e15 else f"{n:.3g}"
    if dt is None:
        return f"{count} samples"
    rate = 1.0 / dt
    rate_text = f"{rate / 1e3:g} kHz" if rate >= 1e3 else f"{rate:g} Hz"
    return f"{count} samples at {rate_text}"


def check(parts: Mapping[str, float], cause: str) -> float:
    """The total of ``parts`` ({what: bytes}) if it is within :func:`memory_limit`, else a ``ValueError``:
    "<cause> needs about <total> (<the largest parts>); the limit is <limit> (MRD_ENV_MEMORY_LIMIT)"."""
    total = float(sum(parts.values()))
    limit = memory_limit()
    if limit is not None and total > limit:
        big = sorted(((b, w) for w, b in parts.items() if b > 0.05 * total), reverse=True)
        detail = "; ".join(f"{format_bytes(b)} for {w}" for b, w in big)
        raise ValueError(f"{cause} needs about {format_bytes(total)} ({detail}); the limit is "
                         f"{format_bytes(limit)} ({ENV_VAR}, see docs/environments.md#memory)")
    return total


def record_bytes(n_samples: float, channels: int, *, generated: bool = False) -> float:
    """Bytes while a record of ``n_samples`` × ``channels`` is built: generated (FFT road, filtered noise), or
    read/resampled (the time grid, the interpolated columns and the record's own copy)."""
    if generated:
        return n_samples * max(GENERATED_SAMPLE_BYTES, FLOAT * 3 * channels)
    return n_samples * FLOAT * (1 + 3 * channels)


@dataclass(frozen=True)
class Budget:
    """What an environment's episode costs per sample of its record beyond the record itself (``row_bytes``: the
    input buffer and the plant's per-episode data of one environment), for the checks made while the records are
    built, before the environment's count and history are known. ``Budget()``: the record alone."""

    row_bytes: float = 0.0

    def check_record(self, n_samples: float, dt: float | None, channels: int, cause: str, *,
                     what: str = "the record", generated: bool = False) -> None:
        """``ValueError`` (see :func:`check`) if a record of ``n_samples`` and the episode on it exceed the
        limit; ``cause`` names the options that set its length."""
        parts = {f"{what} ({samples_text(n_samples, dt)})": record_bytes(n_samples, channels, generated=generated)}
        if self.row_bytes:
            parts["the episode's buffers"] = n_samples * self.row_bytes
        check(parts, cause)

    def check_generation(self, n_samples: float, dt: float | None, channels: int, cause: str, *,
                         grid_samples: float, what: str = "the record", grid: str = "its FFT grid",
                         sample_bytes: float = FFT_SAMPLE_BYTES) -> None:
        """As :meth:`check_record` for a record of ``n_samples`` generated on a longer grid of ``grid_samples``
        (an FFT period that also holds a delay or a lag, e.g. the rear wheels' wheelbase/speed): the grid's
        transient arrays (``sample_bytes`` a sample, default :data:`FFT_SAMPLE_BYTES`) are counted beside the record
        and the episode."""
        parts = {f"{what} ({samples_text(n_samples, dt)})": record_bytes(n_samples, channels),
                 f"{grid} ({samples_text(grid_samples, dt)})": grid_samples * sample_bytes}
        if self.row_bytes:
            parts["the episode's buffers"] = n_samples * self.row_bytes
        check(parts, cause)


def plant_parts(*, nq: int, nd: int, n_states: int, nw: int, n_signals: int, levels: int,
                scratch_rows: int) -> dict[str, float]:
    """The arrays that grow with the plant's size rather than the episode's length: the signal map G (``n_signals``
    rows over the states, forces and inputs; built, then packed into the kernel's constants), the elimination
    matrices of every sub-step ``levels`` (nq², nq·nw, nq·nd and 2·nd² each; kept by the system and packed), and
    the kernel's per-system rows and scratch (``scratch_rows``: environments plus threads), whose Newton matrix
    over the dampers' forces and states grows with (nd·(n_states + 1))². ``nq``: the plant's first-order states
    (2 per degree of freedom); ``nd`` dampers of ``n_states`` internal states each; ``nw`` input channels."""
    n = nq + nd * n_states
    m = max(nd * (n_states + 1), 1)
    g = n_signals * (n + nd + nw)
    lev = levels * (nq * nq + nq * nw + nq * nd + 2 * nd * nd)
    row = 7 * max(n, m) + 13 * nd + m * m + nd * (n_states + 1) * (n_states + 2)
    return {f"the signal map ({n_signals} signals over {n + nd + nw} columns, built and packed)": 3 * FLOAT * g,
            f"the plant's step matrices ({levels} sub-step levels, {nq} states, {nd} dampers; kept and packed)":
                2 * FLOAT * lev,
            f"the kernel's rows and Newton scratch ({scratch_rows} rows; {m}² for {nd} dampers)":
                FLOAT * scratch_rows * row}


def episode_parts(*, rows: int, record_samples: int, num_envs: int, inputs: int, record_channels: int,
                  history_width: int, plant_floats: int, reset_floats: int, per_env_records: bool,
                  generated_channels: int, dt: float) -> dict[str, float]:
    """The arrays of ``num_envs`` episodes of ``rows`` rows (at ``dt``) on records of ``record_samples``:
    the input buffer (``inputs`` columns), the records (``record_channels``; one shared record unless
    ``per_env_records``), the full history (``history_width`` columns; 0 when none is kept), the plant's episode
    data (``plant_floats`` per record sample kept by each episode, or by one if the record is shared;
    ``reset_floats`` computed at a reset and dropped) and, for records generated with ``generated_channels``
    (0: none), generating one."""
    n_rec = num_envs if per_env_records else 1
    envs = f" × {num_envs} environments" if num_envs > 1 else ""
    parts = {
        f"the input buffer ({samples_text(rows, dt)} × {inputs} columns{envs})": num_envs * rows * inputs * FLOAT,
        f"the input records ({samples_text(record_samples)} × {record_channels} channels"
        f"{envs if per_env_records else ''})": n_rec * record_samples * record_channels * FLOAT,
    }
    if history_width:
        parts[f"the history of every row kept for signal() and rendering ({history_width} columns{envs})"] = \
            num_envs * rows * history_width * FLOAT
    if plant_floats or reset_floats:
        parts[f"the plant's episode data ({plant_floats + reset_floats} values per sample"
              f"{envs if per_env_records and plant_floats else ''})"] = \
            (n_rec * plant_floats + reset_floats) * record_samples * FLOAT
    if generated_channels:
        parts["generating a record"] = record_bytes(record_samples, generated_channels, generated=True)
    return parts
