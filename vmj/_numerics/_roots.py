"""The one root finder of the solvers: bracketed (safeguarded) Newton, made differentiable by a
final Newton step taken with gradients (the implicit-function theorem)."""

from __future__ import annotations

import jax.numpy as jnp
import jax
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


def expanding_root(f, hi, iterations: int = 60):
    """Root of `f` on `(0, hi]` with `f(0+) > 0 >= f(hi)` (hi doubled until it brackets):
    safeguarded Newton, then one Newton step with gradients (implicit differentiation).
    Returns `(root, bracketed)`; `bracketed` is False when no root was found (an unbounded
    swing over the potential barrier)."""
    fs = lambda y: lax.stop_gradient(f(y))  # noqa: E731
    hi = lax.stop_gradient(hi)
    for _ in range(8):
        hi = jnp.where(fs(hi) > 0, 2 * hi, hi)
    # (a root at hi itself may evaluate to a rounding-level positive value)
    bracketed = fs(hi) <= 1e-12 * jnp.abs(fs(0.5 * hi))
    # (the slope of f itself: jax.grad of the stopped fs would be zero, i.e. pure bisection)
    fp = lambda y: lax.stop_gradient(jax.grad(f)(y))  # noqa: E731
    y = bracketed_newton(fs, fp, jnp.zeros_like(hi), hi, hi, iterations)
    return implicit_step(f, jax.grad(f), y), bracketed
