"""Bouc–Wen hysteresis, shared by the whole Bouc–Wen family of models.

Review eq. (8): ż = −γ |v| z |z|^(n−1) − β v |z|^n + A v, with v the velocity across the hysteretic
element. For β + γ > 0 and A > 0, z stays inside ±z_s with the saturation z_s = (A/(β+γ))^(1/n).
"""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True)
def bouc_wen_zdot(z, v, A, beta, gamma, n):
    az = abs(z)
    azn = az ** n
    return -gamma * abs(v) * z * (azn / az if az > 0.0 else 0.0) - beta * v * azn + A * v


@nb.njit(cache=True)
def bouc_wen_saturation(A, beta, gamma, n):
    """z_s = (A/(β+γ))^(1/n); infinite when β + γ ≤ 0 (no saturation)."""
    if beta + gamma <= 0.0:
        return math.inf
    return (A / (beta + gamma)) ** (1.0 / n)


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
