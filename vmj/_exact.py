"""Exact (non-smooth) solution of the variable-mass oscillator, half-swing by half-swing.

Within a half-swing the friction sign `s` is fixed and the equation of motion
`m(t) x'' + b x' + c x = -s F(t)` is linear with `m` and `F` affine in `t`. Its Taylor series
about any time `t_j` then obeys a three-term recurrence (`_taylor`), so one substep of length
`h` costs `ORDER` multiply-adds and is accurate to machine precision when
`(sqrt(c/m) + b/m) h <= 2` and `h` stays well inside the distance `m/|dm/dt|` to the zero-mass
singularity; a guard on the series' last terms turns any loss of accuracy into a reported
failure instead of a wrong answer. The velocity zero is
found on the substep's polynomial (bracketed Newton), and its time is made differentiable by one
final Newton step taken with gradients (the implicit-function theorem). A fixed number of
substeps per half-swing keeps the loop shape static, so the solver runs under `jit`, `vmap` and
reverse-mode `grad`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from ._roots import bracketed_newton, implicit_step
from ._solution import RESULTS, DecaySequence

ORDER = 26  #: degree of the Taylor polynomial of a substep
RHO_OMEGA = 2.0  #: substep length in units of 1/(sqrt(c/m) + b/m), the fastest local rate
RHO_MASS = 0.25  #: substep length as a fraction of m(t)/|dm/dt|
NEWTON = 8  #: safeguarded Newton iterations for the velocity zero
TAIL_TOLERANCE = 1e-9  #: largest relative size of a substep series' last two terms


def _taylor(coefficients, s, x, v):
    """Taylor coefficients `x_0..x_ORDER` of the half-swing solution about the current time."""
    m, md, b, c, F, Fd = coefficients
    inv_m = 1.0 / m
    xs = [x, v]
    for n in range(ORDER - 1):
        rhs = c * xs[n] + (n + 1) * (md * n + b) * xs[n + 1]
        if n == 0:
            rhs = rhs + s * F
        elif n == 1:
            rhs = rhs + s * Fd
        xs.append(-rhs * inv_m / ((n + 2) * (n + 1)))
    return xs


def _horner(cs, tau):
    acc = cs[-1]
    for c in cs[-2::-1]:
        acc = acc * tau + c
    return acc


def _derivative(cs):
    return [n * c for n, c in enumerate(cs)][1:]


def _substep_length(model, t):
    m, md, b, c, *_ = model.coefficients(t)
    # |local eigenvalues| <= sqrt(c/m) + b/m: keep their product with h at RHO_OMEGA
    h_omega = RHO_OMEGA / (jnp.sqrt(c / m) + jnp.abs(b) / m)
    amd = jnp.abs(md)
    has_rate = amd > 0
    h_mass = jnp.where(has_rate, RHO_MASS * m / jnp.where(has_rate, amd, 1.0), jnp.inf)
    h = jnp.minimum(h_omega, h_mass)
    return h, h_mass < h_omega, t + h


def march_to_velocity_zero(series, substep, t0, x0, s, max_substeps: int, t_guess):
    """From rest at `(t0, x0)` with friction sign `s`, advance by Taylor substeps to the next
    velocity zero; shared by the exact solvers of every model.

    - `series(t, x, v)`: the Taylor coefficients of the half-swing solution about `t`;
    - `substep(t)`: `(h, limited, t_next)`, the substep length from `t`, whether it is limited by
      the approach of the model's end (zero mass, zero length), and where the substep ends
      (`t + h`, or a breakpoint of a piecewise model);
    - `t_guess`: an estimate of the time of the velocity zero (Newton's start).

    Returns `(found, limited, t1, x1)`: `found` is False when no velocity zero occurred within
    `max_substeps` substeps, or when a series lost accuracy (its last terms not negligible).
    """
    zero = jnp.zeros_like(x0)

    def body(carry, _):
        t, x, v, found, limited, inaccurate, start = carry
        h, end_limited, t_next = substep(t)
        cs = series(t, x, v)
        x1 = _horner(cs, h)
        v1 = _horner(_derivative(cs), h)
        # truncation guard: the last terms of the series must be negligible (a diverging
        # series is off by orders of magnitude; accurate ones stay near 1e-13 or far below)
        k = len(cs) - 1
        tail = jnp.abs(cs[-1]) * h**k + jnp.abs(cs[-2]) * h ** (k - 1)
        bad = tail > TAIL_TOLERANCE * (jnp.abs(x) + jnp.abs(x1) + jnp.abs(v) * h)
        inaccurate = inaccurate | (bad & jnp.logical_not(found))
        hit = jnp.logical_not(found) & (v1 * s <= 0)
        start = jax.tree.map(lambda new, old: jnp.where(hit, new, old), (t, x, v, h), start)
        limited = jnp.where(found, limited, end_limited)
        found = found | hit
        t, x, v = (jnp.where(found, a, b) for a, b in ((t, t_next), (x, x1), (v, v1)))
        return (t, x, v, found, limited, inaccurate, start), None

    false = jnp.array(False)
    init = (t0, x0, zero, false, false, false, (t0, x0, zero, zero))
    (_, _, _, found, limited, inaccurate, start), _ = lax.scan(
        body, init, None, length=max_substeps
    )
    t, x, v, h = start
    t1, x1 = velocity_zero_of(series(t, x, v), t, h, s, t_guess)
    return found & jnp.logical_not(inaccurate), limited, t1, x1


def half_swing(model, t0, x0, s, max_substeps: int):
    """The variable-mass model's half-swing from rest at `(t0, x0)` (see
    `march_to_velocity_zero`); `limited` tells whether the substeps were limited by the
    approach of zero mass."""
    return march_to_velocity_zero(
        lambda t, x, v: _taylor(model.coefficients(t), s, x, v),
        lambda t: _substep_length(model, t),
        t0, x0, s, max_substeps, t0 + _half_period(model, t0),
    )


def _half_period(model, t0):
    """Damped half-period estimated with the mass at mid-swing [s] (a starting guess only)."""
    m, md, b, c, *_ = model.coefficients(t0)
    m = jnp.maximum(m + 0.5 * md * jnp.pi * jnp.sqrt(m / c), 0.5 * m)
    omega2 = jnp.maximum(c / m - (b / (2 * m)) ** 2, 0.25 * c / m)
    return jnp.pi / jnp.sqrt(omega2)


def velocity_zero_of(cs, t, h, s, t_guess):
    """Velocity zero of the substep polynomial `cs` (Taylor coefficients about `t`, valid on
    `[t, t + h]`, moving with sign `s`): `(time, position)`. Shared by the exact solvers."""
    dcs = _derivative(cs)
    ddcs = _derivative(dcs)
    f_cs = [lax.stop_gradient(c * s) for c in dcs]
    fp_cs = [lax.stop_gradient(c * s) for c in ddcs]
    hi = lax.stop_gradient(h)
    tau = jnp.clip(lax.stop_gradient(t_guess - t), 0.05 * hi, hi)
    tau = bracketed_newton(lambda x: _horner(f_cs, x), lambda x: _horner(fp_cs, x),
                           jnp.zeros_like(hi), hi, tau, NEWTON)
    tau = implicit_step(lambda x: _horner(dcs, x), lambda x: _horner(ddcs, x), tau)
    return t + tau, _horner(cs, tau)


def turning_points_exact(model, a0, n: int, max_substeps: int) -> DecaySequence:
    """The first `n` turning points after release from rest at `x = -a0` (see `turning_points`)."""

    def rest_state(t, x):
        """At rest at `(t, x)`: (moves now, release time, stuck for good)."""
        _, _, _, c, F, Fd = model.coefficients(t)
        spring = c * jnp.abs(x)
        moves = spring > F
        decreasing = Fd < 0
        t_release = t + (F - spring) / jnp.where(decreasing, -Fd, 1.0)
        release = jnp.logical_not(moves) & decreasing
        return jnp.where(release, t_release, t), jnp.logical_not(moves | release)

    def body(carry, _):
        t, x, code = carry
        active = code == RESULTS.successful
        t_go, stuck = rest_state(t, x)
        s = -jnp.sign(x)
        found, limited, t1, x1 = half_swing(model, t_go, x, s, max_substeps)
        failure = jnp.where(limited, RESULTS.mass_exhausted, RESULTS.step_limit)
        new_code = jnp.where(
            stuck, RESULTS.stopped, jnp.where(found, RESULTS.successful, failure)
        )
        code = jnp.where(active, new_code, code)
        advance = active & (code == RESULTS.successful)
        t = jnp.where(advance, t1, t)
        x = jnp.where(advance, x1, x)
        return (t, x, code), (t, x, advance & (x1 * s > 0), advance)

    x0 = -a0 * jnp.ones_like(model.m0)
    init = (jnp.zeros_like(x0), x0, jnp.array(RESULTS.successful))
    (t, x, code), (times, positions, crossed, advanced) = lax.scan(body, init, None, length=n)
    _, stuck = rest_state(t, x)
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)
