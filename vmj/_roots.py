"""The one root finder of the solvers: bracketed (safeguarded) Newton, made differentiable by a
final Newton step taken with gradients (the implicit-function theorem)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax


def bracketed_newton(f, fprime, lo, hi, x0, iterations: int):
    """Root of `f` in `[lo, hi]` with `f(lo) > 0 >= f(hi)`: Newton steps from `x0`, falling back
    to bisection whenever a step leaves the bracket. Not differentiated: pass functions of
    `lax.stop_gradient`-ed data and finish with `implicit_step`."""

    def step(_, state):  # a loop, not unrolled: keeps the compiled graph small
        x, lo, hi = state
        fx, dfx = f(x), fprime(x)
        ahead = fx > 0
        lo, hi = jnp.where(ahead, x, lo), jnp.where(ahead, hi, x)
        newton = x - fx / jnp.where(dfx != 0, dfx, 1.0)
        ok = (dfx != 0) & (newton >= lo) & (newton <= hi)
        return jnp.where(ok, newton, 0.5 * (lo + hi)), lo, hi

    x, _, _ = lax.fori_loop(0, iterations, step, (x0, lo, hi))
    return x


def implicit_step(f, fprime, x):
    """One Newton step from the converged root `x` with gradients flowing through `f`: its
    derivative with respect to any parameter is `-(df/dtheta) / (df/dx)`, the implicit one."""
    x = lax.stop_gradient(x)
    slope = fprime(x)
    return x - f(x) / jnp.where(slope != 0, slope, 1.0)
