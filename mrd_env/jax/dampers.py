"""The damper models in JAX: the same equations as their numba functions (:mod:`mrd_env.dampers`), over small
tuples of scalars so that a vmapped batch runs as plain vector arithmetic.

Each model is a :class:`JaxDamper`: ``rhs(p, s, x, xd, u) -> ṡ``, ``force(p, s, x, xd, xdd, u) -> F``,
``partials(p, s, x, xd, xdd, u) -> J`` (the Jacobian of (ṡ, F) with respect to (s, x, ẋ), rows for ṡ then F,
as :class:`~mrd_env.dampers.base.DamperModel` ``partials`` writes it) and ``project(p, s) -> s``; ``p`` is the
model's parameter vector (``Params.as_array()``), ``s`` a tuple of its internal states. The parameter indices
are the numba modules' own ``P_*`` constants.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax.numpy as jnp

from ..dampers import bouc_wen as _bw
from ..dampers import spencer_dyke as _sd


class JaxDamper(NamedTuple):
    name: str
    ns: int
    rhs: Callable
    force: Callable
    partials: Callable
    project: Callable


def _power(a, n):
    """a^n for a > 0 as :func:`mrd_env.dampers.hysteresis.power` (exact for n = 1, 2); 1 where a = 0 (masked
    by the callers), so that no branch makes a NaN that a derivative would pick up."""
    safe = jnp.where(a > 0.0, a, 1.0)
    return jnp.where(n == 2.0, safe * safe, jnp.where(n == 1.0, safe, safe ** n))


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


def _sd_project(p, s):
    return (s[0], clip_to_saturation(s[1], p[_sd.P_A], p[_sd.P_BETA], p[_sd.P_GAMMA], p[_sd.P_N]))


# --- Bouc–Wen --------------------------------------------------------------------------------------------------
def _bw_rhs(p, s, x, xd, u):
    return (bouc_wen_zdot(s[0], xd, p[_bw.P_A], p[_bw.P_BETA], p[_bw.P_GAMMA], p[_bw.P_N]),)


def _bw_force(p, s, x, xd, xdd, u):
    return ((p[_bw.P_C0A] + p[_bw.P_C0B] * u) * xd + (p[_bw.P_K0A] + p[_bw.P_K0B] * u) * (x - p[_bw.P_X0])
            + (p[_bw.P_ALPHA_A] + p[_bw.P_ALPHA_B] * u) * s[0])


def _bw_partials(p, s, x, xd, xdd, u):
    dz, dv = bouc_wen_partials(s[0], xd, p[_bw.P_A], p[_bw.P_BETA], p[_bw.P_GAMMA], p[_bw.P_N])
    zero = jnp.zeros_like(dz)
    return ((dz, zero, dv),
            (p[_bw.P_ALPHA_A] + p[_bw.P_ALPHA_B] * u, p[_bw.P_K0A] + p[_bw.P_K0B] * u, p[_bw.P_C0A] + p[_bw.P_C0B] * u))


def _bw_project(p, s):
    return (clip_to_saturation(s[0], p[_bw.P_A], p[_bw.P_BETA], p[_bw.P_GAMMA], p[_bw.P_N]),)


#: The models with a JAX twin, by their registry name.
MODELS = {
    _sd.SpencerDyke.name: JaxDamper(_sd.SpencerDyke.name, 2, _sd_rhs, _sd_force, _sd_partials, _sd_project),
    _bw.BoucWen.name: JaxDamper(_bw.BoucWen.name, 1, _bw_rhs, _bw_force, _bw_partials, _bw_project),
}


def jax_damper(name: str) -> JaxDamper:
    """The JAX twin of the damper model ``name``; ``ValueError`` naming the ones that have one."""
    if name not in MODELS:
        raise ValueError(f"damper = {name!r} has no JAX twin yet; available: {sorted(MODELS)}")
    return MODELS[name]
