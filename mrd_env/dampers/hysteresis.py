"""Bouc–Wen hysteresis, shared by the whole Bouc–Wen family of models.

Review eq. (8): ż = −γ |v| z |z|^(n−1) − β v |z|^n + A v, with v the velocity across the hysteretic
element. For β + γ > 0 and A > 0, z stays inside ±z_s with the saturation z_s = (A/(β+γ))^(1/n).
"""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True)
def power(a, n):
    """a^n for a >= 0; the common integer exponents without a call to pow (the hot path of every step)."""
    if n == 2.0:
        return a * a
    if n == 1.0:
        return a
    return a ** n


@nb.njit(cache=True)
def bouc_wen_zdot(z, v, A, beta, gamma, n):
    az = abs(z)
    azn1 = power(az, n - 1.0) if az > 0.0 else (1.0 if n == 1.0 else 0.0)
    return -gamma * abs(v) * z * azn1 - beta * v * az * azn1 + A * v


@nb.njit(cache=True)
def bouc_wen_partials(z, v, A, beta, gamma, n):
    """(∂ż/∂z, ∂ż/∂v) of eq. (8)."""
    az = abs(z)
    azn1 = power(az, n - 1.0) if az > 0.0 else (1.0 if n == 1.0 else 0.0)
    sz = 1.0 if z > 0.0 else (-1.0 if z < 0.0 else 0.0)
    sv = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    dz = -n * azn1 * (gamma * abs(v) + beta * v * sz)
    dv = -gamma * sv * z * azn1 - beta * az * azn1 + A
    return dz, dv


@nb.njit(cache=True)
def bouc_wen_saturation(A, beta, gamma, n):
    """z_s = (A/(β+γ))^(1/n); infinite when β + γ ≤ 0 (no saturation)."""
    if beta + gamma <= 0.0:
        return math.inf
    ratio = A / (beta + gamma)
    return math.sqrt(ratio) if n == 2.0 else ratio ** (1.0 / n)


@nb.njit(cache=True)
def clip_to_saturation(z, A, beta, gamma, n):
    """An implicit step may overshoot the saturation bound: keep z in the invariant set [−z_s, z_s].

    ±z_s is invariant only for γ ≥ 0 (at z = z_s with v < 0, ż = v·2γA/(β+γ)); otherwise z is left as is.
    """
    if gamma < 0.0:
        return z
    zs = bouc_wen_saturation(A, beta, gamma, n)
    if z > zs:
        return zs
    if z < -zs:
        return -zs
    return z


class BoucWenSaturation:
    """Mixin for models whose state z follows eq. (8) with parameters ``A``, ``beta``, ``gamma``, ``n``."""

    def saturation(self) -> float:
        """z_s = (A/(β+γ))^(1/n) in m."""
        p = self.params
        return float(bouc_wen_saturation(p.A, p.beta, p.gamma, p.n))
