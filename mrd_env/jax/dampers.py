"""The damper models in JAX: the same equations as their numba functions (:mod:`mrd_env.dampers`), over small
tuples of scalars so that a vmapped batch runs as plain vector arithmetic. Every model of the library has one.

Each model is a :class:`JaxDamper`: ``rhs(p, s, x, xd, u) -> ṡ``, ``force(p, s, x, xd, xdd, u) -> F``,
``partials(p, s, x, xd, xdd, u) -> J`` (the Jacobian of (ṡ, F) with respect to (s, x, ẋ), rows for ṡ then F,
as :class:`~mrd_env.dampers.base.DamperModel` ``partials`` writes it) and ``project(p, s, x, xd, u) -> s`` (between
steps: the invariant set and the discrete modes, e.g. the acceleration branch of :mod:`~mrd_env.dampers.
acceleration_branch`, switched from the stroke rate at the step's end); ``p`` is the model's parameter vector
(``Params.as_array()``), ``s`` a tuple of its internal states. The parameter indices are the numba modules' own
``P_*`` constants.

The Jacobian is what the numba kernel uses: the model's analytic ``partials`` where it has them (Spencer–Dyke,
Bouc–Wen), else the kernel's forward differences (:func:`fd_partials`, the same steps), so that the exact scheme's
Newton iterates are the kernel's. Branches are ``jnp.where`` over values that are finite on both sides (the
argument of an unselected power, division or ``tanh`` is made harmless first), so that derivatives stay finite.
"""
from __future__ import annotations

import contextlib
import contextvars
from typing import Callable, NamedTuple

import jax.numpy as jnp

from ..dampers import ali_ramaswamy as _ar
from ..dampers import bi_viscous as _bv
from ..dampers import bingham as _bi
from ..dampers import bouc_wen as _bw
from ..dampers import dahl as _da
from ..dampers import dominguez as _do
from ..dampers import gamota_filisko as _gf
from ..dampers import hyperbolic_tangent as _ht
from ..dampers import hysteretic_bi_viscous as _hb
from ..dampers import lugre as _lg
from ..dampers import modified_bouc_wen as _mb
from ..dampers import nonsymmetric_bouc_wen as _nb
from ..dampers import sigmoid as _sg
from ..dampers import spencer_dyke as _sd


class JaxDamper(NamedTuple):
    name: str
    ns: int
    rhs: Callable
    force: Callable
    partials: Callable
    project: Callable


def fd_partials(rhs: Callable, force: Callable, ns: int) -> Callable:
    """The Jacobian by forward differences, as the numba kernel's ``fd_partials`` computes it for the models without
    analytic derivatives: column c perturbs state c, then x, then ẋ by 1e-7·max(|value|, 1e-3)."""
    def partials(p, s, x, xd, xdd, u):
        s = tuple(s)
        F0 = force(p, s, x, xd, xdd, u)
        g0 = rhs(p, s, x, xd, u)
        cols = []
        for c in range(ns + 2):
            sc, xc, vc = s, x, xd
            if c < ns:
                d = 1.0e-7 * jnp.maximum(jnp.abs(s[c]), 1.0e-3)
                sc = s[:c] + (s[c] + d,) + s[c + 1:]
            elif c == ns:
                d = 1.0e-7 * jnp.maximum(jnp.abs(x), 1.0e-3)
                xc = x + d
            else:
                d = 1.0e-7 * jnp.maximum(jnp.abs(xd), 1.0e-3)
                vc = xd + d
            F1 = force(p, sc, xc, vc, xdd, u)
            g1 = rhs(p, sc, xc, vc, u)
            cols.append([(g1[k] - g0[k]) / d for k in range(ns)] + [(F1 - F0) / d])
        return tuple(tuple(cols[c][r] for c in range(ns + 2)) for r in range(ns + 1))
    return partials


def exact_partials(rhs: Callable, force: Callable, ns: int) -> Callable:
    """The Jacobian by forward-mode differentiation (``jax.jacfwd``) of the model's equations: exact where the
    forward differences carry truncation and rounding noise (the differentiable scheme's option
    ``jacobian="exact"``; the exact scheme keeps the kernel's Jacobian, so as to iterate as the kernel does)."""
    import jax

    def partials(p, s, x, xd, xdd, u):
        def f(z):
            sz = tuple(z[i] for i in range(ns))
            g = rhs(p, sz, z[ns], z[ns + 1], u)
            return jnp.stack([*(jnp.asarray(v, jnp.float64) for v in g), jnp.asarray(force(p, sz, z[ns], z[ns + 1],
                                                                                            xdd, u), jnp.float64)])
        J = jax.jacfwd(f)(jnp.stack([jnp.asarray(v, jnp.float64) for v in (*tuple(s), x, xd)]))
        return tuple(tuple(J[r, c] for c in range(ns + 2)) for r in range(ns + 1))
    return partials


def _fd_model(cls, rhs, force, project) -> JaxDamper:
    ns = len(cls.state_names)
    return JaxDamper(cls.name, ns, rhs, force, fd_partials(rhs, force, ns), project)


# --- shared pieces (the numba helpers' twins) ------------------------------------------------------------------
_FAST_POWER = contextvars.ContextVar("mrd_env_jax_fast_power", default=False)


def _power(a, n):
    """a^n for a > 0 as :func:`mrd_env.dampers.hysteresis.power` (exact for n = 1, 2); 1 where a = 0 (masked
    by the callers), so that no branch makes a NaN that a derivative would pick up."""
    safe = jnp.where(a > 0.0, a, 1.0)
    general = jnp.exp(n * jnp.log(safe)) if _FAST_POWER.get() else safe ** n
    return jnp.where(n == 2.0, safe * safe, jnp.where(n == 1.0, safe, general))


@contextlib.contextmanager
def fast_power():
    """Inside it, the models' general exponent a^n (an n other than 1 or 2: every branch of a ``jnp.where`` is
    evaluated, so it costs in every step) is traced as exp(n·ln a): XLA's vectorised exp and log, about twice as
    fast as its pow on the CPU, within a few ulps of it. The differentiable scheme traces its step inside it; the
    exact scheme keeps pow, as the numba kernel."""
    token = _FAST_POWER.set(True)
    try:
        yield
    finally:
        _FAST_POWER.reset(token)


def _azn1(z, n):
    az = jnp.abs(z)
    return az, jnp.where(az > 0.0, _power(az, n - 1.0), jnp.where(n == 1.0, 1.0, 0.0))


def bouc_wen_zdot(z, v, A, beta, gamma, n):
    az, azn1 = _azn1(z, n)
    return -gamma * jnp.abs(v) * z * azn1 - beta * v * az * azn1 + A * v


def bouc_wen_partials(z, v, A, beta, gamma, n):
    az, azn1 = _azn1(z, n)
    sz = jnp.sign(z)
    sv = jnp.sign(v)
    dz = -n * azn1 * (gamma * jnp.abs(v) + beta * v * sz)
    dv = -gamma * sv * z * azn1 - beta * az * azn1 + A
    return dz, dv


def clip_to_saturation(z, A, beta, gamma, n):
    """z within ±z_s (:func:`mrd_env.dampers.hysteresis.clip_to_saturation`)."""
    ratio = A / jnp.where(beta + gamma > 0.0, beta + gamma, 1.0)
    zs = jnp.where(beta + gamma <= 0.0, jnp.inf, jnp.where(n == 2.0, jnp.sqrt(ratio), ratio ** (1.0 / n)))
    return jnp.where(gamma < 0.0, z, jnp.where(z > zs, zs, jnp.where(z < -zs, -zs, z)))


def smooth_sign(v, v_s):
    """tanh(v / v_s), the exact sign where v_s = 0 (:func:`mrd_env.dampers.base.smooth_sign`)."""
    return jnp.where(v_s <= 0.0, jnp.sign(v), jnp.tanh(v / jnp.where(v_s > 0.0, v_s, 1.0)))


def clip(r, bound):
    """r within ±bound, as the numba models' ``if r > b: r = b elif r < −b: r = −b``."""
    return jnp.where(r > bound, bound, jnp.where(r < -bound, -bound, r))


def _no_states_rhs(p, s, x, xd, u):
    return ()


def _no_projection(p, s, x, xd, u):
    return tuple(s)


def _held_branch_rhs(p, s, x, xd, u, tau):
    """The filtered velocity's q̇ = (ẋ − q)/τ and the held branch σ̇ = 0 (:mod:`~mrd_env.dampers.acceleration_branch`)."""
    return ((xd - s[0]) / tau, jnp.zeros_like(s[1]))


def _branch_projection(p, s, x, xd, u, tau, a_s):
    """σ ← tanh(â / a_s), â = (ẋ − q)/τ, switched between steps (:func:`~mrd_env.dampers.acceleration_branch.branch`)."""
    return (s[0], smooth_sign((xd - s[0]) / tau, a_s))


def _bouc_wen_state(mod):
    """(rhs, project) of a model whose one state z follows eq. (8) driven by ẋ, with the parameters at the module's
    ``P_A``, ``P_BETA``, ``P_GAMMA``, ``P_N``: ż, and z kept within ±z_s."""
    def rhs(p, s, x, xd, u):
        return (bouc_wen_zdot(s[0], xd, p[mod.P_A], p[mod.P_BETA], p[mod.P_GAMMA], p[mod.P_N]),)

    def project(p, s, x, xd, u):
        return (clip_to_saturation(s[0], p[mod.P_A], p[mod.P_BETA], p[mod.P_GAMMA], p[mod.P_N]),)
    return rhs, project


_bw_rhs, _bw_project = _bouc_wen_state(_bw)
_mb_rhs, _mb_project = _bouc_wen_state(_mb)
_ar_rhs, _ar_project = _bouc_wen_state(_ar)


# --- Spencer–Dyke ----------------------------------------------------------------------------------------------
def _sd_coefficients(p, u):
    c0 = p[_sd.P_C0A] + p[_sd.P_C0B] * u
    c1 = p[_sd.P_C1A] + p[_sd.P_C1B] * u
    alpha = p[_sd.P_ALPHA_A] + p[_sd.P_ALPHA_B] * u
    return c0, c1, alpha


def _sd_ydot(p, s, x, xd, u):
    c0, c1, alpha = _sd_coefficients(p, u)
    return (alpha * s[1] + c0 * xd + p[_sd.P_K0] * (x - s[0])) / (c0 + c1)


def _sd_rhs(p, s, x, xd, u):
    yd = _sd_ydot(p, s, x, xd, u)
    return (yd, bouc_wen_zdot(s[1], xd - yd, p[_sd.P_A], p[_sd.P_BETA], p[_sd.P_GAMMA], p[_sd.P_N]))


def _sd_force(p, s, x, xd, xdd, u):
    return (p[_sd.P_C1A] + p[_sd.P_C1B] * u) * _sd_ydot(p, s, x, xd, u) + p[_sd.P_K1] * (x - p[_sd.P_X0])


def _sd_partials(p, s, x, xd, xdd, u):
    c0, c1, alpha = _sd_coefficients(p, u)
    k0 = p[_sd.P_K0]
    den = c0 + c1
    yd = (alpha * s[1] + c0 * xd + k0 * (x - s[0])) / den
    dy, dz, dx, dv = -k0 / den, alpha / den, k0 / den, c0 / den
    bz, bw = bouc_wen_partials(s[1], xd - yd, p[_sd.P_A], p[_sd.P_BETA], p[_sd.P_GAMMA], p[_sd.P_N])
    return ((dy, dz, dx, dv),
            (-bw * dy, bz - bw * dz, -bw * dx, bw * (1.0 - dv)),
            (c1 * dy, c1 * dz, c1 * dx + p[_sd.P_K1], c1 * dv))


def _sd_project(p, s, x, xd, u):
    return (s[0], clip_to_saturation(s[1], p[_sd.P_A], p[_sd.P_BETA], p[_sd.P_GAMMA], p[_sd.P_N]))


# --- Bouc–Wen (and the non-symmetrical one: the same parameters first, the same force and saturation) ----------
def _bw_force(p, s, x, xd, xdd, u):
    return ((p[_bw.P_C0A] + p[_bw.P_C0B] * u) * xd + (p[_bw.P_K0A] + p[_bw.P_K0B] * u) * (x - p[_bw.P_X0])
            + (p[_bw.P_ALPHA_A] + p[_bw.P_ALPHA_B] * u) * s[0])


def _bw_partials(p, s, x, xd, xdd, u):
    dz, dv = bouc_wen_partials(s[0], xd, p[_bw.P_A], p[_bw.P_BETA], p[_bw.P_GAMMA], p[_bw.P_N])
    zero = jnp.zeros_like(dz)
    return ((dz, zero, dv),
            (p[_bw.P_ALPHA_A] + p[_bw.P_ALPHA_B] * u, p[_bw.P_K0A] + p[_bw.P_K0B] * u, p[_bw.P_C0A] + p[_bw.P_C0B] * u))


def _nb_rhs(p, s, x, xd, u):
    v = xd - p[_nb.P_MU] * smooth_sign(x, p[_nb.P_X_S])
    return (bouc_wen_zdot(s[0], v, p[_nb.P_A], p[_nb.P_BETA], p[_nb.P_GAMMA], p[_nb.P_N]),)


# --- modified Bouc–Wen (m ẍ with the ẍ the scheme hands over, as the kernel does) -----------------------------
def _shear_thinning_damping(a1, a2, pw, v):
    """a1 exp(−(a2 |ẋ|)^p) (:func:`mrd_env.dampers.modified_bouc_wen.shear_thinning_damping`); (0)^p = 0 without
    the infinite derivative of the power at 0 (c(ẋ)·ẋ is differentiable there)."""
    a = a2 * jnp.abs(v)
    return a1 * jnp.exp(-jnp.where(a > 0.0, jnp.where(a > 0.0, a, 1.0) ** pw, 0.0))


def _mb_force(p, s, x, xd, xdd, u):
    c = _shear_thinning_damping(p[_mb.P_A1A] + p[_mb.P_A1B] * u, p[_mb.P_A2], p[_mb.P_P], xd)
    return (p[_mb.P_M] * xdd + c * xd + (p[_mb.P_KA] + p[_mb.P_KB] * u) * (x - p[_mb.P_X0])
            + (p[_mb.P_ALPHA_A] + p[_mb.P_ALPHA_B] * u) * s[0])


# --- Ali & Ramaswamy ---------------------------------------------------------------------------------------------
def _ar_quad(p, o, a, u):
    return p[o] + p[o + 1] * a + p[o + 2] * a * a + (p[o + 3] + p[o + 4] * a + p[o + 5] * a * a) * u


def _ar_force(p, s, x, xd, xdd, u):
    a = p[_ar.P_X_A]
    return (_ar_quad(p, _ar.P_C1, a, u) * xd + _ar_quad(p, _ar.P_K1, a, u) * x + _ar_quad(p, _ar.P_ALPHA1, a, u) * s[0]
            + p[_ar.P_F0])


# --- Dahl and LuGre: eq. (8) with n = 1, β = 0 -------------------------------------------------------------------
def _da_rhs(p, s, x, xd, u):
    return (bouc_wen_zdot(s[0], xd, p[_da.P_SIGMA], 0.0, p[_da.P_SIGMA], 1.0),)


def _da_force(p, s, x, xd, xdd, u):
    return ((p[_da.P_C0A] + p[_da.P_C0B] * u) * xd + p[_da.P_K0] * x + (p[_da.P_FD_A] + p[_da.P_FD_B] * u) * s[0]
            + p[_da.P_F0])


def _da_project(p, s, x, xd, u):
    return (clip_to_saturation(s[0], p[_da.P_SIGMA], 0.0, p[_da.P_SIGMA], 1.0),)


def _lg_zdot(p, z, xd):
    return bouc_wen_zdot(z, xd, 1.0, 0.0, p[_lg.P_SIGMA0] * p[_lg.P_A0], 1.0)


def _lg_rhs(p, s, x, xd, u):
    return (_lg_zdot(p, s[0], xd),)


def _lg_force(p, s, x, xd, xdd, u):
    return ((p[_lg.P_SIGMA0] + p[_lg.P_SIGMA0B] * u) * s[0] + p[_lg.P_SIGMA1] * _lg_zdot(p, s[0], xd)
            + (p[_lg.P_SIGMA2A] + p[_lg.P_SIGMA2B] * u) * xd + p[_lg.P_F0])


def _lg_project(p, s, x, xd, u):
    return (clip_to_saturation(s[0], 1.0, 0.0, p[_lg.P_SIGMA0] * p[_lg.P_A0], 1.0),)


# --- memoryless laws: Bingham, bi-viscous, hyperbolic tangent, Dominguez ---------------------------------------
def _bi_force(p, s, x, xd, xdd, u):
    return ((p[_bi.P_FC_A] + p[_bi.P_FC_B] * u) * smooth_sign(xd, p[_bi.P_V_S]) + (p[_bi.P_C0A] + p[_bi.P_C0B] * u) * xd
            + p[_bi.P_F0])


def bi_viscous_curve(v, c_pre, c_ps, f_yield, v_shift):
    """c_ps v + clip((c_pre − c_ps) v − c_pre v_shift, ±F_yield) (:func:`mrd_env.dampers.bi_viscous.bi_viscous_curve`)."""
    return c_ps * v + clip((c_pre - c_ps) * v - c_pre * v_shift, f_yield)


def _bv_force(p, s, x, xd, xdd, u):
    return bi_viscous_curve(xd, p[_bv.P_C_PRE_A] + p[_bv.P_C_PRE_B] * u, p[_bv.P_C_PS_A] + p[_bv.P_C_PS_B] * u,
                            p[_bv.P_FY_A] + p[_bv.P_FY_B] * u, 0.0) + p[_bv.P_F0]


def _ht_force(p, s, x, xd, xdd, u):
    return ((p[_ht.P_C_A] + p[_ht.P_C_B] * u) * xd + p[_ht.P_K] * x
            + (p[_ht.P_ALPHA_A] + p[_ht.P_ALPHA_B] * u)
            * jnp.tanh(p[_ht.P_BETA] * xd + p[_ht.P_DELTA] * smooth_sign(x, p[_ht.P_X_S]))
            + p[_ht.P_F0])


def _current_law(I, p1, p2, p3, p4, i_c):
    """Eqs. (15)–(17) of :func:`mrd_env.dampers.dominguez.current_law` (the exponential's argument kept ≤ 0 where
    it is not selected)."""
    above = p1 + p2 * (1.0 - jnp.exp(-p3 * jnp.where(I > i_c, I - i_c, 0.0)))
    return jnp.where(I > i_c, above, p4 + (p1 - p4) * I / i_c)


def _do_force(p, s, x, xd, xdd, u):
    i_c = p[_do.P_I_C]
    c0 = _current_law(u, p[_do.P_C1], p[_do.P_C2], p[_do.P_C3], p[_do.P_C4], i_c)
    k0 = p[_do.P_K1] + p[_do.P_K2] * u
    alpha = _current_law(u, p[_do.P_ALPHA1], p[_do.P_ALPHA2], p[_do.P_ALPHA3], p[_do.P_ALPHA4], i_c)
    gamma = p[_do.P_GAMMA1] - p[_do.P_GAMMA2] * u
    fz0 = _current_law(u, p[_do.P_FZ01], p[_do.P_FZ02], p[_do.P_FZ03], p[_do.P_FZ04], i_c)
    sg = jnp.sqrt(gamma)
    r = jnp.minimum(sg * fz0 / alpha, 1.0 - 1e-12)
    z = jnp.tanh(sg * xd + smooth_sign(x, p[_do.P_X_S]) * jnp.arctanh(r)) / sg
    scaling = p[_do.P_D1] * p[_do.P_OMEGA] ** p[_do.P_D2] * p[_do.P_D3] * p[_do.P_X_MAX] ** p[_do.P_D4]
    return scaling * (c0 * xd + k0 * x + alpha * z)


# --- Gamota–Filisko ---------------------------------------------------------------------------------------------
def _gf_rhs(p, s, x, xd, u):
    f_c = p[_gf.P_FC_A] + p[_gf.P_FC_B] * u
    c0 = p[_gf.P_C0A] + p[_gf.P_C0B] * u
    P = s[1]
    v1 = jnp.where(P > f_c, (P - f_c) / c0, jnp.where(P < -f_c, (P + f_c) / c0, 0.0))  # the Bingham element
    kelvin = (s[1] - s[0]) / p[_gf.P_C1]
    return ((p[_gf.P_K1A] + p[_gf.P_K1B] * u) * kelvin, (p[_gf.P_K2A] + p[_gf.P_K2B] * u) * (xd - v1 - kelvin))


def _gf_force(p, s, x, xd, xdd, u):
    return s[1] + p[_gf.P_F0]


# --- the acceleration-branch models: hysteretic bi-viscous, sigmoid ---------------------------------------------
def _hb_poly(p, i, u):
    return p[i] + u * (p[i + 1] + u * (p[i + 2] + u * (p[i + 3] + u * p[i + 4])))


def _hb_rhs(p, s, x, xd, u):
    return _held_branch_rhs(p, s, x, xd, u, p[_hb.P_TAU])


def _hb_force(p, s, x, xd, xdd, u):
    return (bi_viscous_curve(xd, _hb_poly(p, _hb.P_C_PRE_0, u), _hb_poly(p, _hb.P_C_PS_0, u),
                             _hb_poly(p, _hb.P_FY_0, u), _hb_poly(p, _hb.P_V0_0, u) * s[1]) + p[_hb.P_F0])


def _hb_project(p, s, x, xd, u):
    return _branch_projection(p, s, x, xd, u, p[_hb.P_TAU], p[_hb.P_A_S])


def _sg_rhs(p, s, x, xd, u):
    return _held_branch_rhs(p, s, x, xd, u, p[_sg.P_TAU])


def _sg_force(p, s, x, xd, xdd, u):
    return ((p[_sg.P_FY_A] + p[_sg.P_FY_B] * u) * jnp.tanh(0.5 * (p[_sg.P_BETA] * (xd - p[_sg.P_V_H] * s[1])))
            + (p[_sg.P_C_A] + p[_sg.P_C_B] * u) * xd + p[_sg.P_F0])


def _sg_project(p, s, x, xd, u):
    return _branch_projection(p, s, x, xd, u, p[_sg.P_TAU], p[_sg.P_A_S])


#: Every model of the library, by its registry name (a test checks that none is missing).
MODELS = {m.name: m for m in (
    JaxDamper(_sd.SpencerDyke.name, 2, _sd_rhs, _sd_force, _sd_partials, _sd_project),
    JaxDamper(_bw.BoucWen.name, 1, _bw_rhs, _bw_force, _bw_partials, _bw_project),
    _fd_model(_nb.NonsymmetricBoucWen, _nb_rhs, _bw_force, _bw_project),
    _fd_model(_mb.ModifiedBoucWen, _mb_rhs, _mb_force, _mb_project),
    _fd_model(_ar.AliRamaswamy, _ar_rhs, _ar_force, _ar_project),
    _fd_model(_da.Dahl, _da_rhs, _da_force, _da_project),
    _fd_model(_lg.LuGre, _lg_rhs, _lg_force, _lg_project),
    _fd_model(_bi.Bingham, _no_states_rhs, _bi_force, _no_projection),
    _fd_model(_bv.BiViscous, _no_states_rhs, _bv_force, _no_projection),
    _fd_model(_ht.HyperbolicTangent, _no_states_rhs, _ht_force, _no_projection),
    _fd_model(_do.Dominguez, _no_states_rhs, _do_force, _no_projection),
    _fd_model(_gf.GamotaFilisko, _gf_rhs, _gf_force, _no_projection),
    _fd_model(_hb.HystereticBiViscous, _hb_rhs, _hb_force, _hb_project),
    _fd_model(_sg.Sigmoid, _sg_rhs, _sg_force, _sg_project),
)}


#: The Jacobians a model's twin can use: the numba kernel's (analytic or its forward differences), or exact.
JACOBIANS = ("kernel", "exact")


def jax_damper(name: str, jacobian: str = "kernel") -> JaxDamper:
    """The JAX twin of the damper model ``name`` with the Jacobian ``jacobian`` (:data:`JACOBIANS`); ``ValueError``
    naming the ones that have one."""
    if name not in MODELS:
        raise ValueError(f"damper = {name!r} has no JAX twin; available: {sorted(MODELS)}")
    if jacobian not in JACOBIANS:
        raise ValueError(f"jacobian must be one of {JACOBIANS}, got {jacobian!r}")
    m = MODELS[name]
    return m if jacobian == "kernel" else m._replace(partials=exact_partials(m.rhs, m.force, m.ns))
