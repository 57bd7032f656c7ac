"""Truncated power series: evaluation, derivative and products (the exact solvers' Taylor
arithmetic)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

__all__ = [
    "horner",
    "horner_and_derivative",
    "slope_and_curvature",
    "derivative",
    "cauchy",
    "cauchy_term",
]


def horner(cs, tau):
    """`sum_j cs[j] tau^j` for a list of coefficients."""
    acc = cs[-1]
    for c in cs[-2::-1]:
        acc = acc * tau + c
    return acc


def horner_and_derivative(cs, tau):
    """`(p(tau), p'(tau))` of `p = sum_j cs[j] tau^j` in one pass over the coefficients."""
    value, slope = cs[-1], jnp.zeros_like(cs[-1])
    for c in cs[-2::-1]:
        slope = slope * tau + value
        value = value * tau + c
    return value, slope


def slope_and_curvature(cs, tau):
    """`(p'(tau), p''(tau))` of `p = sum_j cs[j] tau^j` in one pass over the coefficients
    themselves (no derivative's coefficients made first)."""
    value, slope, half_curvature = cs[-1], jnp.zeros_like(cs[-1]), jnp.zeros_like(cs[-1])
    for c in cs[-2::-1]:
        half_curvature = half_curvature * tau + slope
        slope = slope * tau + value
        value = value * tau + c
    return slope, 2 * half_curvature


def derivative(cs):
    """Coefficients of the derivative of the series `cs` (a list)."""
    return [n * c for n, c in enumerate(cs)][1:]


def cauchy(a, b):
    """First `len(a)` coefficients of the product of two series (1-D arrays)."""
    k = a.shape[0]
    i = np.arange(k)
    idx = i[:, None] - i[None, :]  # row n, column j -> b[n - j]
    mat = jnp.where(idx >= 0, b[np.clip(idx, 0, k - 1)], 0.0)
    return mat @ a


def cauchy_term(a, b, n):
    """Coefficient `n` (a traced integer) of the product of two series (1-D arrays):
    `sum_{i <= n} a[i] b[n - i]`, for recurrences that build the series one term at a time."""
    i = jnp.arange(a.shape[0])
    return jnp.sum(jnp.where(i <= n, a * b[jnp.clip(n - i, 0, a.shape[0] - 1)], 0.0))
