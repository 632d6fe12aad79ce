"""Where the compiled driver finds everything: one list of names shared by :class:`~.driver.Driver` (which packs
by it) and the kernel (``_driver_template.py`` imports the slot numbers below, compile-time constants there).

A driver's data is four arrays plus the inputs and outputs (numba's dispatch costs about 30 ns per argument):

* ``fc`` (float constants): the arrays of :data:`LAYOUT` ``["float_constants"]``, flattened one after another;
* ``ic`` (int constants): a header of :data:`HEADER_SLOT` ints per constant array (its offset, then up to four
  dimensions), the dims, then (offset, length) of every per-system float field, then the int arrays' data;
* ``fs``/``is_``: one row of float/int state per system (fields :data:`LAYOUT` ``["state"]`` and
  ``["int_state"]``), plus one scratch row per thread.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

LAYOUT = {
    "float_constants": ("C", "D", "AINV", "BBAR", "MQ", "PP", "G", "SOS", "SCAL", "NOISE", "LIMITS", "CLIMITS"),
    "int_constants": ("MEAS", "RCOLS", "LCOLS", "STAT_COLS", "FILTERS", "CCOLS", "CSIDES", "CTERMS", "PCOLS"),
    "dims": ("N", "NH", "NPAR", "NSUB", "MAX_LEVEL", "HIST_MODE", "CMD_INPUT", "DOSE_COL", "NORMALIZED",
             "DELAY", "HISTORY", "SCRATCH"),
    "scalars": ("DT", "VMIN", "VMAX", "RTOL", "ATOL", "PEN_CONST", "PEN_STEP"),
    "state": ("Y", "U", "F", "P", "LAG", "CMDQ", "CMD", "ZI", "RSCALE", "STATS", "DOSE", "RING", "FIFO", "ROW",
              "REWARD", "COST", "POWER"),
    "int_state": ("K", "NSTEPS", "STATUS", "KEY", "COUNTER", "NSUB", "FIFO_POS", "RING_POS", "ROWS", "REASON",
                  "FAIL_STEP", "SUBSTEPS", "CMDQ_POS"),
    "status": ("RUNNING", "TERMINATED", "TRUNCATED", "DIVERGED", "BAD_ACTION"),
}

HEADER_SLOT = 5  # ints per constant array in ic's header: its offset and up to four dimensions
_NF = len(LAYOUT["float_constants"])
_NI = len(LAYOUT["int_constants"])

# The slot numbers, spelled out so that a reader, an IDE or ruff resolves them in the template; the unpacking
# fails if a list above grows, and _check() below if an order differs.
# ic[F_<name>]: header of the float constant <name> (offset into fc, dimensions)
(F_C, F_D, F_AINV, F_BBAR, F_MQ, F_PP, F_G, F_SOS, F_SCAL, F_NOISE, F_LIMITS,
 F_CLIMITS) = range(0, HEADER_SLOT * _NF, HEADER_SLOT)
# ic[I_<name>]: header of the int constant <name> (offset into ic, dimensions)
(I_MEAS, I_RCOLS, I_LCOLS, I_STAT_COLS, I_FILTERS, I_CCOLS, I_CSIDES, I_CTERMS,
 I_PCOLS) = range(HEADER_SLOT * _NF, HEADER_SLOT * (_NF + _NI), HEADER_SLOT)
D_DIMS = HEADER_SLOT * (_NF + _NI)  # ic[D_DIMS + DIM_<name>]: the dimension <name>
(DIM_N, DIM_NH, DIM_NPAR, DIM_NSUB, DIM_MAX_LEVEL, DIM_HIST_MODE, DIM_CMD_INPUT, DIM_DOSE_COL, DIM_NORMALIZED,
 DIM_DELAY, DIM_HISTORY, DIM_SCRATCH) = range(len(LAYOUT["dims"]))
# scal[SC_<name>]: the float scalars (one constant array, SCAL)
SC_DT, SC_VMIN, SC_VMAX, SC_RTOL, SC_ATOL, SC_PEN_CONST, SC_PEN_STEP = range(len(LAYOUT["scalars"]))
_S0 = D_DIMS + len(LAYOUT["dims"])
# ic[S_<name>], ic[S_<name> + 1]: offset and length of the per-system float field <name> in a row of fs
(S_Y, S_U, S_F, S_P, S_LAG, S_CMDQ, S_CMD, S_ZI, S_RSCALE, S_STATS, S_DOSE, S_RING, S_FIFO, S_ROW,
 S_REWARD, S_COST, S_POWER) = range(_S0, _S0 + 2 * len(LAYOUT["state"]), 2)
HEADER_LEN = _S0 + 2 * len(LAYOUT["state"])
# is_[b, T_<name>]: the per-system int field <name>
(T_K, T_NSTEPS, T_STATUS, T_KEY, T_COUNTER, T_NSUB, T_FIFO_POS, T_RING_POS, T_ROWS, T_REASON, T_FAIL_STEP,
 T_SUBSTEPS, T_CMDQ_POS) = range(len(LAYOUT["int_state"]))

#: An episode's status (int field STATUS; ``Driver.step`` returns system 0's).
RUNNING, TERMINATED, TRUNCATED, DIVERGED, BAD_ACTION = range(len(LAYOUT["status"]))

#: What the history buffer H receives (``Processing.history_mode``): nothing, every row of the episode, or the
#: rows of the last period.
HIST_NONE, HIST_FULL, HIST_PERIOD = range(3)

# Rows of the per-damper scratch Vd holding one step's delayed commands: va until the switch time ts, then vb
# (written by the driver's delayed_commands or the inverses' hold, read by the SDIRK step).
VD_VA, VD_VB, VD_TS = 10, 11, 12

# Records that group the kernel's arguments (numba passes their fields as it would separate arguments): the
# driver's arrays, the plant's matrices (per sub-step level) and what is computed from the outputs.
CoreArrays = namedtuple("CoreArrays", "fc ic fs is_ W H action obs")
PlantArrays = namedtuple("PlantArrays", "C D Ainv Bbar Mq PP")
OutputArrays = namedtuple("OutputArrays", "G sos filt scal noise limits")
# ... and those of one step of one system: the dampers' parameters (nd, n_params) and command dynamics (nd, 3),
# the state (Y plant and damper states, U effective commands, Fz forces), how a step is taken (dt, the finest
# sub-step level, the tolerances) and the views of the scratch (see ``_kernel_template.workspace_views``).
DamperArrays = namedtuple("DamperArrays", "P lag")
SystemState = namedtuple("SystemState", "Y U Fz")
StepControl = namedtuple("StepControl", "dt max_level atol rtol")
Workspace = namedtuple("Workspace", "Vn Vd Vx K Iw Jd")


def _check() -> None:
    g = globals()
    for prefix, group, first, step in (("F_", "float_constants", 0, HEADER_SLOT),
                                       ("I_", "int_constants", HEADER_SLOT * _NF, HEADER_SLOT),
                                       ("DIM_", "dims", 0, 1), ("SC_", "scalars", 0, 1), ("S_", "state", _S0, 2),
                                       ("T_", "int_state", 0, 1), ("", "status", 0, 1)):
        for i, name in enumerate(LAYOUT[group]):
            if g[prefix + name] != first + step * i:
                raise AssertionError(f"layout: {prefix}{name} is out of order")


_check()


def pack(floats: dict, ints: dict, dims: dict, sizes: dict):
    """(fc, ic, field offsets): the constants in one float and one int array with the headers the kernel reads,
    and the per-system field offsets {name: (offset, length)}."""
    fc_parts, ic_head = [], []
    o = 0
    for name in LAYOUT["float_constants"]:
        a = np.ascontiguousarray(floats[name], dtype=np.float64)
        shape = list(a.shape) + [1] * (HEADER_SLOT - 1 - a.ndim)
        ic_head += [o, *shape]
        fc_parts.append(a.ravel())
        o += a.size
    int_data = []
    o_int = HEADER_LEN
    for name in LAYOUT["int_constants"]:
        a = np.ascontiguousarray(np.asarray(ints[name], dtype=np.int64))
        if a.ndim == 1:
            a = a.reshape(-1)
        shape = list(a.shape) + [1] * (HEADER_SLOT - 1 - a.ndim)
        ic_head += [o_int, *shape]
        int_data.append(a.ravel())
        o_int += a.size
    ic_head += [int(dims[n]) for n in LAYOUT["dims"]]
    fields, o = {}, 0
    for name in LAYOUT["state"]:
        fields[name] = (o, int(sizes[name]))
        ic_head += [o, int(sizes[name])]
        o += int(sizes[name])
    assert len(ic_head) == HEADER_LEN
    fc = np.concatenate(fc_parts) if fc_parts else np.zeros(0)
    ic = np.concatenate([np.array(ic_head, dtype=np.int64)] + int_data)
    return np.ascontiguousarray(fc), np.ascontiguousarray(ic), fields
