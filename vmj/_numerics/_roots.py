"""The one root finder of the solvers: bracketed (safeguarded) Newton, made differentiable by a
final Newton step taken with gradients (the implicit-function theorem)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from equinox.internal import unvmap_any
from jax import lax

from ._scan import computed_once, zeros_of_lanes

#: a lane has converged once a Newton step moved it by less than this fraction of its bracket
#: (quadratic convergence: the final `implicit_step` then leaves an error far below rounding)
CONVERGED = 1e-8


def converged_fraction(dtype) -> float:
    """`CONVERGED`, or four units of rounding of `dtype` where they are coarser (float32:
    4.8e-7): a step cannot move a float32 root by less than its rounding, so a test at 1e-8
    would never pass and every lane would run to the iteration limit."""
    return max(CONVERGED, 4 * float(jnp.finfo(dtype).eps))


def bracketed_newton(f, lo, hi, x0, iterations: int, unrolled: bool = False, batch: bool = True):
    """Root of a function in `[lo, hi]`, positive at `lo` and `<= 0` at `hi`; `f(x)` returns its
    value and slope `(y, dy/dx)`. Newton steps from `x0`, falling back to bisection whenever a
    step leaves the bracket. A lane stops (and keeps its value) once a step moved it by at most
    `converged_fraction` of its initial bracket or hit `f = 0`; the loop ends when every lane
    of a `vmap`ped batch has stopped, or after `iterations` steps. Not
    differentiated: pass functions of `lax.stop_gradient`-ed data and finish with
    `implicit_step`.

    `unrolled`: exactly `iterations` steps written out instead of a `while_loop`, for a start
    so close that a few steps always suffice (one fused kernel instead of a loop of small
    ones: the smoothed turning points within a step of the dense output).

    `batch`: the loop's `f(x)` is `computed_once` (for a batch, whose kernels' arithmetic is
    its cost); False for a single lane, whose cost is the number of kernels."""

    def cond(state):
        i, _, _, _, done = state
        return (i < iterations) & unvmap_any(jnp.logical_not(done))

    def step(state):
        i, x, lo, hi, done = state
        fx, dfx = computed_once(f(x), i) if batch and not unrolled else f(x)
        ahead = fx > 0
        lo_new, hi_new = jnp.where(ahead, x, lo), jnp.where(ahead, hi, x)
        newton = x - fx / jnp.where(dfx != 0, dfx, 1.0)
        ok = (dfx != 0) & (newton >= lo_new) & (newton <= hi_new)
        x_new = jnp.where(ok, newton, 0.5 * (lo_new + hi_new))
        keep = lambda old, new: jnp.where(done, old, new)  # noqa: E731
        converged = (jnp.abs(x_new - x) <= tol) | (fx == 0)
        return (i + 1, keep(x, x_new), keep(lo, lo_new), keep(hi, hi_new), done | converged)

    dtype = jnp.result_type(x0, lo, hi)
    x0, lo, hi = (jnp.asarray(a, dtype) for a in jnp.broadcast_arrays(x0, lo, hi))
    tol = converged_fraction(dtype) * jnp.abs(hi - lo)
    state = (jnp.array(0), x0, lo, hi, zeros_of_lanes(x0, bool))
    if unrolled:
        for _ in range(iterations):
            state = step(state)
    else:
        state = lax.while_loop(cond, step, state)
    return state[1]


def implicit_step(f, x):
    """One Newton step from the converged root `x` with gradients flowing through
    `f(x) -> (value, slope)`: its derivative with respect to any parameter is
    `-(df/dtheta) / (df/dx)`, the implicit one."""
    x = lax.stop_gradient(x)
    value, slope = f(x)
    return x - value / jnp.where(slope != 0, slope, 1.0)


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
    y = bracketed_newton(lambda y: (fs(y), fp(y)), jnp.zeros_like(hi), hi, hi, iterations)
    return implicit_step(lambda y: (f(y), jax.grad(f)(y)), y), bracketed
