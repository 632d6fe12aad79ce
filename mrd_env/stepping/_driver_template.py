"""Template of the compiled driver: one call advances N systems over one period (see
:mod:`mrd_env.stepping.driver`).

Appended to the stepping kernel of a damper model (``_kernel_template.py``) in the generated module, whose names
it imports here on ``# injected`` lines (dropped by the generator); the slot numbers (``F_<name>``, ``I_<name>``,
``S_<name>``, ``T_<name>``, ``DIM_<name>``, ``SC_<name>``) come from :mod:`mrd_env.stepping.layout`, so that the
Python side and the kernel agree on one list of names.

Per system b and per step of the period: the command (the held action, or a column of the input record)
pushed into the queue of past commands that the command delay reads, the physics (``macro_step``), the named
outputs h = G·[Y, F, W] into one row, the command columns, the online filters (second-order sections,
transposed direct form II as ``scipy.signal.sosfilt``), the quadratic reward terms, the limits (termination),
the constraint costs (rows at which a soft limit is exceeded, per term and any), the running statistics of
chosen columns (sum of squares, peak, fourth power and 1 s running r.m.s. of one column) and the control power
(Σ |force·velocity| over chosen pairs: peak and sum); after the period: the costs in seconds, the measurement
(with Gaussian noise from a counter-based generator keyed per system and episode), the sensor delay and history
FIFO, the observation.
"""
import math

import numba as nb

from mrd_env.stepping._kernel_template import delayed_commands, end_forces, macro_step, workspace_views  # injected
from mrd_env.stepping.injected import ns  # injected
from mrd_env.stepping.layout import (
    BAD_ACTION, D_DIMS, DIM_CMD_INPUT, DIM_DELAY, DIM_DOSE_COL, DIM_HIST_MODE, DIM_HISTORY, DIM_MAX_LEVEL, DIM_N,
    DIM_NH, DIM_NORMALIZED, DIM_NPAR, DIM_NSUB, DIM_SCRATCH, DIVERGED, F_AINV, F_BBAR, F_C, F_CLIMITS, F_D, F_G,
    F_LIMITS, F_MQ, F_NOISE, F_PP, F_SCAL, F_SOS, HIST_FULL, HIST_PERIOD, I_CCOLS, I_CSIDES, I_CTERMS, I_FILTERS,
    I_LCOLS, I_MEAS, I_PCOLS, I_RCOLS, I_STAT_COLS, RUNNING, S_CMD, S_CMDQ, S_COST, S_DOSE, S_F, S_FIFO, S_LAG, S_P,
    S_POWER, S_RING, S_ROW, S_RSCALE, S_REWARD, S_STATS, S_U, S_Y, S_ZI, SC_ATOL, SC_DT, SC_PEN_CONST, SC_PEN_STEP,
    SC_RTOL, SC_VMAX, SC_VMIN, T_CMDQ_POS, T_COUNTER, T_FAIL_STEP, T_FIFO_POS, T_K, T_KEY, T_NSTEPS, T_NSUB,
    T_REASON, T_RING_POS, T_ROWS, T_STATUS, T_SUBSTEPS, TERMINATED, TRUNCATED, CoreArrays, DamperArrays,
    OutputArrays, PlantArrays, StepControl, SystemState)
from mrd_env.stepping.scheme import OK


@nb.njit(inline='always')
def _f1(fc, ic, h):
    """The constant array whose header (offset, shape...) starts at ic[h], as a 1-D view of fc."""
    return fc[ic[h]:ic[h] + ic[h + 1]]


@nb.njit(inline='always')
def _f2(fc, ic, h):
    a, b = ic[h + 1], ic[h + 2]
    return fc[ic[h]:ic[h] + a * b].reshape((a, b))


@nb.njit(inline='always')
def _f3(fc, ic, h):
    a, b, c = ic[h + 1], ic[h + 2], ic[h + 3]
    return fc[ic[h]:ic[h] + a * b * c].reshape((a, b, c))


@nb.njit(inline='always')
def _f4(fc, ic, h):
    a, b, c, d = ic[h + 1], ic[h + 2], ic[h + 3], ic[h + 4]
    return fc[ic[h]:ic[h] + a * b * c * d].reshape((a, b, c, d))


@nb.njit(inline='always')
def _i1(ic, h):
    return ic[ic[h]:ic[h] + ic[h + 1]]


@nb.njit(inline='always')
def _i2(ic, h):
    a, b = ic[h + 1], ic[h + 2]
    return ic[ic[h]:ic[h] + a * b].reshape((a, b))


@nb.njit(inline='always')
def _state(fs, ic, b, h):
    """System b's per-system field whose (offset, length) is at ic[h]."""
    return fs[b, ic[h]:ic[h] + ic[h + 1]]


@nb.njit(inline='always')
def _mix64(x):
    """splitmix64's finaliser: a well-mixed 64-bit hash of x (uint64 arithmetic wraps)."""
    x = (x ^ (x >> nb.uint64(30))) * nb.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> nb.uint64(27))) * nb.uint64(0x94D049BB133111EB)
    return x ^ (x >> nb.uint64(31))


@nb.njit(inline='always')
def _gauss(key, counter):
    """A standard normal deviate from (key, counter): two uniforms from splitmix64 hashes, Box–Muller.
    Counter-based, so that system b of a batch draws exactly what a batch of one with the same key draws."""
    base = nb.uint64(key) + nb.uint64(counter) * nb.uint64(0x9E3779B97F4A7C15) * nb.uint64(2)
    h1 = _mix64(base + nb.uint64(0x9E3779B97F4A7C15))
    h2 = _mix64(base + nb.uint64(0x3C6EF372FE94F82A))
    u1 = ((h1 >> nb.uint64(11)) + nb.uint64(1)) * (1.0 / 9007199254740992.0)  # (0, 1]
    u2 = (h2 >> nb.uint64(11)) * (1.0 / 9007199254740992.0)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@nb.njit(inline='always')
def _row(G, Y, Fz, w, cmd, h, nsig, nd):
    """h[:nsig] = G·[Y, F, w]; h[nsig:nsig + nd] = the command."""
    n = Y.shape[0]
    nw = w.shape[0]
    for i in range(nsig):
        acc = 0.0
        for k in range(n):
            acc += G[i, k] * Y[k]
        for k in range(nd):
            acc += G[i, n + k] * Fz[k]
        for k in range(nw):
            acc += G[i, n + nd + k] * w[k]
        h[i] = acc
    for j in range(nd):
        h[nsig + j] = cmd[j]


@nb.njit(inline='always')
def _count_costs(h, ccols, csides, climits, cterms, cost):
    """Count one row in the cost field: cost[1 + t] += 1 if a constraint of term t is violated at it (|h| > limit,
    h > limit or h < −limit by its side), cost[0] += 1 if any is."""
    any_violated = False
    for t in range(cterms.shape[0] - 1):
        violated = False
        for i in range(cterms[t], cterms[t + 1]):
            x = h[ccols[i]]
            if csides[i] == 0:
                x = abs(x)
            elif csides[i] < 0:
                x = -x
            if x > climits[i]:
                violated = True
        if violated:
            cost[1 + t] += 1.0
            any_violated = True
    if any_violated:
        cost[0] += 1.0


@nb.njit(inline='always')
def _close_costs(cost, n_terms, dt):
    """The period's row counts [any, term 1..T] into seconds, added to the episode's totals behind them."""
    for i in range(n_terms + 1):
        c = cost[i] * dt
        cost[i] = c
        cost[n_terms + 1 + i] += c


@nb.njit(inline='always')
def _power(h, pcols):
    """Σ_i |h[f_i]·h[v_i]| over the (force, velocity) column pairs: the control power of the row (W)."""
    p = 0.0
    for i in range(pcols.shape[0]):
        p += abs(h[pcols[i, 0]] * h[pcols[i, 1]])
    return p


@nb.njit(inline='always')
def _measure_and_observe(ic, fs, is_, b, h, noise, obs_out):
    """Measure h (with noise), push it into the delay/history FIFO and write the observation of system b."""
    meas = _i1(ic, I_MEAS)
    n_meas = meas.shape[0]
    delay = ic[D_DIMS + DIM_DELAY]
    hist = ic[D_DIMS + DIM_HISTORY]
    depth = delay + hist
    fifo = _state(fs, ic, b, S_FIFO).reshape((depth, n_meas))
    pos = (is_[b, T_FIFO_POS] + 1) % depth
    key = is_[b, T_KEY]
    counter = is_[b, T_COUNTER]
    for i in range(n_meas):
        val = h[meas[i]]
        if noise[i] > 0.0:
            val += noise[i] * _gauss(key, counter)
            counter += 1
        fifo[pos, i] = val
    is_[b, T_COUNTER] = counter
    is_[b, T_FIFO_POS] = pos
    # observation: the measurements of steps k − delay − hist + 1 .. k − delay, oldest first
    for s in range(hist):
        slot = (pos - delay - (hist - 1 - s)) % depth
        for i in range(n_meas):
            obs_out[b, s * n_meas + i] = fifo[slot, i]


@nb.njit(cache=True, _nrt=False)
def core_reset(fc, ic, fs, is_, W, H, obs, mask):
    """Start an episode for every system with mask[b]: forces and outputs at the initial state (row 0),
    statistics from row 0, the FIFO filled with the first measurement (noise drawn), the observation."""
    N = fs.shape[0] - ic[D_DIMS + DIM_SCRATCH]
    C = _f3(fc, ic, F_C)
    D = _f3(fc, ic, F_D)
    G = _f2(fc, ic, F_G)
    noise = _f1(fc, ic, F_NOISE)
    nd = C.shape[1]
    nq = C.shape[2]
    n = ic[D_DIMS + DIM_N]
    nsig = G.shape[0]
    nH = ic[D_DIMS + DIM_NH]
    npar = ic[D_DIMS + DIM_NPAR]
    hist_mode = ic[D_DIMS + DIM_HIST_MODE]
    stat_cols = _i1(ic, I_STAT_COLS)
    Vd = workspace_views(fs[N], is_[N], nq, nd, n, D.shape[2]).Vd
    for b in range(N):
        if not mask[b]:
            continue
        Y = _state(fs, ic, b, S_Y)
        U = _state(fs, ic, b, S_U)
        Fz = _state(fs, ic, b, S_F)
        P = _state(fs, ic, b, S_P).reshape((nd, npar))
        cmd = _state(fs, ic, b, S_CMD)
        h = _state(fs, ic, b, S_ROW)
        status = end_forces(C, D, P, Y, U, W[b, 0], Fz, Vd)
        queue = _state(fs, ic, b, S_CMDQ).reshape((-1, nd))
        for j in range(nd):
            cmd[j] = U[j]
            for i in range(queue.shape[0]):  # the commands before the episode: the settled effective one
                queue[i, j] = U[j]
        is_[b, T_CMDQ_POS] = 0
        for i in range(nH):
            h[i] = 0.0
        _row(G, Y, Fz, W[b, 0], cmd, h, nsig, nd)
        if hist_mode == HIST_FULL:
            for i in range(nH):
                H[b, 0, i] = h[i]
        st = _state(fs, ic, b, S_STATS)
        for i in range(stat_cols.shape[0]):
            x = h[stat_cols[i]]
            st[2 * i] = x * x
            st[2 * i + 1] = abs(x)
        dose = _state(fs, ic, b, S_DOSE)
        dose[0] = 0.0
        dose[1] = 0.0
        dose[2] = 0.0
        cost = _state(fs, ic, b, S_COST)
        for i in range(cost.shape[0]):
            cost[i] = 0.0
        power = _state(fs, ic, b, S_POWER)
        power[0] = _power(h, _i2(ic, I_PCOLS))  # the peak from row 0, as the statistics; the sum from row 1
        power[1] = 0.0
        for i in range(ic[S_RING + 1]):
            fs[b, ic[S_RING] + i] = 0.0
        is_[b, T_RING_POS] = 0
        is_[b, T_K] = 0
        is_[b, T_ROWS] = 1
        is_[b, T_SUBSTEPS] = 0
        is_[b, T_STATUS] = RUNNING if status == OK else DIVERGED
        is_[b, T_NSUB] = 1
        is_[b, T_COUNTER] = 0
        # the FIFO starts full of the first measurement (noise drawn once)
        depth = ic[D_DIMS + DIM_DELAY] + ic[D_DIMS + DIM_HISTORY]
        is_[b, T_FIFO_POS] = depth - 1
        _measure_and_observe(ic, fs, is_, b, h, noise, obs)
        meas_n = ic[I_MEAS + 1]
        fifo = _state(fs, ic, b, S_FIFO).reshape((depth, meas_n))
        for s in range(1, depth):
            for i in range(meas_n):
                fifo[s, i] = fifo[0, i]
        for s in range(ic[D_DIMS + DIM_HISTORY]):
            for i in range(meas_n):
                obs[b, s * meas_n + i] = fifo[0, i]


@nb.njit(cache=True, _nrt=False)
def _advance_one(b, core, plant, outputs, wf, wi):
    """One period of system b (see the module docstring) with the scratch wf, wi; returns its status."""
    fc, ic, fs, is_, W, H, action, obs = core
    C = plant.C
    D = plant.D
    G, sos, filt, scal, noise, limits = outputs
    nd = C.shape[1]
    n = ic[D_DIMS + DIM_N]
    nsig = G.shape[0]
    nH = ic[D_DIMS + DIM_NH]
    npar = ic[D_DIMS + DIM_NPAR]
    n_sub = ic[D_DIMS + DIM_NSUB]
    max_level = ic[D_DIMS + DIM_MAX_LEVEL]
    hist_mode = ic[D_DIMS + DIM_HIST_MODE]
    cmd_col = ic[D_DIMS + DIM_CMD_INPUT]
    dose_col = ic[D_DIMS + DIM_DOSE_COL]
    dt = scal[SC_DT]
    v_min = scal[SC_VMIN]
    v_max = scal[SC_VMAX]
    rcols = _i1(ic, I_RCOLS)
    lcols = _i1(ic, I_LCOLS)
    stat_cols = _i1(ic, I_STAT_COLS)
    ccols = _i1(ic, I_CCOLS)
    csides = _i1(ic, I_CSIDES)
    cterms = _i1(ic, I_CTERMS)
    n_terms = cterms.shape[0] - 1
    climits = _f1(fc, ic, F_CLIMITS)
    pcols = _i2(ic, I_PCOLS)
    Y = _state(fs, ic, b, S_Y)
    U = _state(fs, ic, b, S_U)
    Fz = _state(fs, ic, b, S_F)
    P = _state(fs, ic, b, S_P).reshape((nd, npar))
    lag = _state(fs, ic, b, S_LAG).reshape((nd, 3))
    cmd = _state(fs, ic, b, S_CMD)
    queue = _state(fs, ic, b, S_CMDQ).reshape((-1, nd))
    ws = workspace_views(wf, wi, C.shape[2], nd, n, D.shape[2])
    Vd = ws.Vd
    zi = _state(fs, ic, b, S_ZI).reshape((sos.shape[0], 2))
    rscale = _state(fs, ic, b, S_RSCALE)
    st = _state(fs, ic, b, S_STATS)
    dose = _state(fs, ic, b, S_DOSE)
    ring = _state(fs, ic, b, S_RING)
    h = _state(fs, ic, b, S_ROW)
    cost = _state(fs, ic, b, S_COST)
    power = _state(fs, ic, b, S_POWER)
    damper = DamperArrays(P, lag)
    state = SystemState(Y, U, Fz)
    control = StepControl(dt, max_level, scal[SC_ATOL], scal[SC_RTOL])
    # the action: validated (every damper's before any command is written, so that a refused step changes
    # nothing), clipped to the Box and mapped onto [v_min, v_max] when normalised
    if cmd_col < 0:
        for j in range(nd):
            if not math.isfinite(action[b * nd + j]):
                return BAD_ACTION
        for j in range(nd):
            a = action[b * nd + j]
            if ic[D_DIMS + DIM_NORMALIZED] == 1:
                a = min(max(a, -1.0), 1.0)
                a = v_min + (a + 1.0) * 0.5 * (v_max - v_min)
            cmd[j] = min(max(a, v_min), v_max)
    k0 = is_[b, T_K] * n_sub
    nsub = is_[b, T_NSUB]
    for i in range(n_terms + 1):  # the period's rows in violation, counted below (seconds at its end)
        cost[i] = 0.0
    total = 0.0
    status = RUNNING
    window = ring.shape[0]
    for k in range(n_sub):
        r = k0 + k
        if cmd_col >= 0:  # the commands are columns of the input record (rig, identification)
            for j in range(nd):
                cmd[j] = W[b, r, cmd_col + j]
        pos = (is_[b, T_CMDQ_POS] + 1) % queue.shape[0]
        is_[b, T_CMDQ_POS] = pos
        for j in range(nd):
            queue[pos, j] = cmd[j]
        delayed_commands(queue, pos, lag, dt, Vd)
        stat, used, nsub = macro_step(plant, damper, state, W[b, r], W[b, r + 1], control, nsub, ws)
        if stat != OK:
            is_[b, T_REASON] = stat
            is_[b, T_FAIL_STEP] = r
            _close_costs(cost, n_terms, dt)  # the rows before the failure count
            return DIVERGED
        is_[b, T_SUBSTEPS] += used
        _row(G, Y, Fz, W[b, r + 1], cmd, h, nsig, nd)
        for f in range(filt.shape[0]):  # online filters: input column, output column, first section, count
            x = h[filt[f, 0]]
            for s in range(filt[f, 2], filt[f, 2] + filt[f, 3]):
                yv = sos[s, 0] * x + zi[s, 0]
                zi[s, 0] = sos[s, 1] * x - sos[s, 4] * yv + zi[s, 1]
                zi[s, 1] = sos[s, 2] * x - sos[s, 5] * yv
                x = yv
            h[filt[f, 1]] = x
        for i in range(rcols.shape[0]):
            v = h[rcols[i]]
            total += rscale[i] * v * v
        for i in range(lcols.shape[0]):
            if abs(h[lcols[i]]) > limits[i]:
                status = TERMINATED
        if n_terms > 0:
            _count_costs(h, ccols, csides, climits, cterms, cost)
        if pcols.shape[0] > 0:
            pw = _power(h, pcols)
            power[1] += pw
            if pw > power[0]:
                power[0] = pw
        for i in range(stat_cols.shape[0]):
            x = h[stat_cols[i]]
            st[2 * i] += x * x
            ax = abs(x)
            if ax > st[2 * i + 1]:
                st[2 * i + 1] = ax
        if dose_col >= 0:  # fourth-power dose and the maximum of the running r.m.s. over the ring's window
            x2 = h[dose_col] * h[dose_col]
            dose[0] += x2 * x2
            rp = is_[b, T_RING_POS]
            dose[1] += x2 - ring[rp]
            ring[rp] = x2
            is_[b, T_RING_POS] = (rp + 1) % window
            run = math.sqrt(max(dose[1], 0.0) / window)
            if run > dose[2]:
                dose[2] = run
        if hist_mode == HIST_FULL:
            for i in range(nH):
                H[b, r + 1, i] = h[i]
        elif hist_mode == HIST_PERIOD:
            for i in range(nH):
                H[b, k, i] = h[i]
    _close_costs(cost, n_terms, dt)
    is_[b, T_NSUB] = nsub
    is_[b, T_K] += 1
    is_[b, T_ROWS] += n_sub
    reward = -total / n_sub
    if status == TERMINATED:
        reward -= scal[SC_PEN_CONST] + scal[SC_PEN_STEP] * is_[b, T_NSTEPS]
    elif is_[b, T_NSTEPS] - is_[b, T_K] <= 0:
        status = TRUNCATED
    fs[b, ic[S_REWARD]] = reward
    _measure_and_observe(ic, fs, is_, b, h, _f1(fc, ic, F_NOISE), obs)
    return status


@nb.njit(cache=True, parallel=True)
def core_step_parallel(fc, ic, fs, is_, W, H, action, obs):
    """Advance every system whose status is RUNNING by one period (the others are left as they are), the
    systems split into as many chunks as there are scratch rows, the chunks running in parallel (numba
    threads); each system's result is the one the serial call (:func:`run_systems` over all systems) gives.
    Returns the status of system 0."""
    n_chunks = ic[D_DIMS + DIM_SCRATCH]
    N = fs.shape[0] - n_chunks
    for c in nb.prange(n_chunks):
        run_systems(fc, ic, fs, is_, W, H, action, obs, N + c, c * N // n_chunks, (c + 1) * N // n_chunks)
    return is_[0, T_STATUS]


@nb.njit(cache=True, _nrt=False)
def run_systems(fc, ic, fs, is_, W, H, action, obs, scratch, b0, b1):
    """Advance systems b0..b1−1 whose status is RUNNING by one period, with the scratch row ``scratch`` of fs
    and is_ (see :mod:`mrd_env.stepping.layout`; the serial call: scratch N, systems 0..N−1, what a scalar
    environment makes). Returns the status of system 0 (the scalar environment's).

    Python calls it directly (no thin wrapper above it: every compiled level re-links and re-generates the code
    of the levels below it, 2–3 s of a first use's compilation)."""
    core = CoreArrays(fc, ic, fs, is_, W, H, action, obs)
    plant = PlantArrays(_f3(fc, ic, F_C), _f3(fc, ic, F_D), _f3(fc, ic, F_AINV), _f3(fc, ic, F_BBAR),
                        _f3(fc, ic, F_MQ), _f4(fc, ic, F_PP))
    outputs = OutputArrays(_f2(fc, ic, F_G), _f2(fc, ic, F_SOS), _i2(ic, I_FILTERS), _f1(fc, ic, F_SCAL),
                           _f1(fc, ic, F_NOISE), _f1(fc, ic, F_LIMITS))
    wf = fs[scratch]
    wi = is_[scratch]
    m = max(plant.C.shape[1] * (ns + 1), 1)
    for b in range(b0, b1):
        if is_[b, T_STATUS] != RUNNING:
            continue
        wi[m] = -1
        status = _advance_one(b, core, plant, outputs, wf, wi)
        is_[b, T_STATUS] = status
    return is_[0, T_STATUS]
