"""Solvers of the rope model: exact Taylor half-swings (`method="exact"`) and the smoothed ODE
(`method="smooth"`); the `u = 0` energy map (`method="energy"`) is in `_rope_averaging`.

Exact solver. Within a half-swing the friction sign `s` is fixed and, on each polynomial piece
of the length profile, `g_k(tau) = 1/l(t + tau)^k` has a Taylor series given by a recurrence
(`l` is a polynomial of degree <= 2). The Taylor coefficients of `x` then follow from

    m (n+2)(n+1) x_{n+2} = -A [e (g_1 x)_n + b (g_2 x^2)_n + d (g_3 x^3)_n]
                           + [n = 0] (2 m l_2 - A T s)

with Cauchy products `( )_n`, so a substep of length `h` costs O(ORDER^2) multiply-adds and is
accurate to machine precision when `h` is well inside the radius of convergence: `h` is at most
`RHO / omega_tangent(amplitude)` (the cubic spring shortens the radius), `RHO_LENGTH l/|l'|` (the
singularity at `l = 0`) and the distance to the next breakpoint of the profile. The velocity zero
is found on the substep polynomial with the variable-mass solver's root finder (differentiable
through one Newton step), and a fixed number of substeps per half-swing keeps the loop static
(`jit`, `vmap`, reverse-mode `grad`).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import lax

from ._exact import march_to_velocity_zero
from ._rope import Rope
from ._smooth import turning_points_smooth
from ._solution import RESULTS, DecaySequence
from ._solve import register_solver

ORDER = 26  #: degree of the Taylor polynomial of a substep
RHO = 1.0  #: substep length in units of 1/omega_tangent(amplitude)
RHO_LENGTH = 0.25  #: substep length as a fraction of l/|dl/dt|


def _cauchy(a, b):
    """First `len(a)` coefficients of the product of two series."""
    k = a.shape[0]
    i = np.arange(k)
    idx = i[:, None] - i[None, :]  # row n, column j -> b[n - j]
    mat = jnp.where(idx >= 0, b[np.clip(idx, 0, k - 1)], 0.0)
    return mat @ a


def _series(model: Rope, t, s, x, v):
    """Taylor coefficients `x_0..x_ORDER` of the half-swing solution about `t` (a list)."""
    l, l1, l2 = model.length.local(t)
    k = ORDER + 1
    i = jnp.arange(k)

    def reciprocal(n, g):  # g = 1/l(t + tau): l0 g_n + l1 g_{n-1} + l2 g_{n-2} = 0
        return g.at[n].set(-(l1 * g[n - 1] + l2 * jnp.where(n >= 2, g[n - 2], 0.0)) / l)

    g1 = lax.fori_loop(1, k, reciprocal, jnp.zeros(k, dtype=l.dtype).at[0].set(1.0 / l))
    g2 = _cauchy(g1, g1)
    g3 = _cauchy(g2, g1)
    A, m = model.A, model.m
    force0 = 2 * m * l2 - A * model.T * s

    def term(a, b, n):  # (a b)_n
        return jnp.sum(jnp.where(i <= n, a * b[jnp.clip(n - i, 0, k - 1)], 0.0))

    def body(n, carry):
        xs, x2, x3 = carry
        x2 = x2.at[n].set(term(xs, xs, n))
        x3 = x3.at[n].set(term(x2, xs, n))
        rhs = -A * (model.e * term(g1, xs, n) + model.b * term(g2, x2, n)
                    + model.d * term(g3, x3, n))
        rhs = rhs + jnp.where(n == 0, force0, 0.0)
        return xs.at[n + 2].set(rhs / (m * (n + 1) * (n + 2))), x2, x3

    zeros = jnp.zeros(k, dtype=jnp.result_type(x, v, l))
    xs0 = zeros.at[0].set(x).at[1].set(v)
    xs, _, _ = lax.fori_loop(0, ORDER - 1, body, (xs0, zeros, zeros))
    return [xs[j] for j in range(k)]


def _substep(model: Rope, t, amp):
    """Substep length from `t`, whether it is limited by the approach of `l = 0`, and where it
    ends (`t + h`, or a breakpoint of the profile)."""
    l, rate, _ = model.length.local(t)
    h_omega = RHO / model.omega(t, amp)
    moving = rate != 0
    h_len = jnp.where(moving, RHO_LENGTH * l / jnp.where(moving, jnp.abs(rate), 1.0), jnp.inf)
    brk = model.length.next_break(t)
    h = jnp.minimum(jnp.minimum(h_omega, h_len), brk - t)
    return h, h_len < h_omega, jnp.where(h >= brk - t, brk, t + h)


def half_swing(model: Rope, t0, x0, s, max_substeps: int):
    """From rest at `(t0, x0)` with friction sign `s` to the next velocity zero:
    `(found, length_limited, t1, x1)` (see `march_to_velocity_zero`)."""
    amp = jnp.abs(x0) + jnp.abs(model.m * model.length.accel(t0)) / (model.A * model.e) * \
        model.length.length(t0)
    return march_to_velocity_zero(
        lambda t, x, v: _series(model, t, s, x, v),
        lambda t: _substep(model, t, amp),
        t0, x0, s, max_substeps, t0 + jnp.pi / model.omega(t0, amp),
    )


PIECES = 3  #: polynomial pieces of a length profile searched for a release (Braking has 3)


def release_time(model: Rope, t, x):
    """A mass stuck at `x` from time `t` is pushed off again when the net force (spring plus
    frame inertia) jumps above the static friction `A T` where a new piece of the length profile
    starts (a drum that begins to brake). Returns `(t_release, never)`.

    A force that grows continuously inside a piece (a shortening rope stiffens) does not give
    a new swing: the mass is then dragged along the edge of the stick zone, `|spring| = A T`,
    with a velocity that only touches zero (quasi-static creep, no further turning points). The
    solver reports that as the end of the decay (`stopped`)."""
    static = model.friction_force()
    found = jnp.array(False)
    t_rel = t
    p0 = t
    for _ in range(PIECES):
        brk = model.length.next_break(p0)
        p0 = jnp.where(jnp.isfinite(brk), brk, p0)
        here = jnp.logical_not(found) & jnp.isfinite(brk) & (brk < model.lifetime()) & (
            jnp.abs(model.net_force(p0, x)) > static)
        t_rel = jnp.where(here, p0, t_rel)
        found = found | here
    return t_rel, jnp.logical_not(found)


def rope_turning_points_exact(model: Rope, a0, n: int, max_substeps: int) -> DecaySequence:
    """The first `n` turning points after release from rest at `x = -a0` (exact solver)."""
    static = model.friction_force()

    def rest(t, x):
        """At rest at `(t, x)`: (direction of the next swing, start time, stuck for good)."""
        stuck = jnp.abs(model.net_force(t, x)) <= static
        t_rel, never = release_time(model, t, x)
        t_go = jnp.where(stuck, t_rel, t)
        force = model.net_force(t_go, x)
        return jnp.where(force >= 0, 1.0, -1.0), t_go, stuck & never

    def body(carry, _):
        t, x, code = carry
        active = code == RESULTS.successful
        s, t_go, stuck = rest(t, x)
        found, limited, t1, x1 = half_swing(model, t_go, x, s, max_substeps)
        failure = jnp.where(limited, RESULTS.length_exhausted, RESULTS.step_limit)
        new_code = jnp.where(stuck, RESULTS.stopped, jnp.where(found, RESULTS.successful, failure))
        code = jnp.where(active, new_code, code)
        advance = active & (code == RESULTS.successful)
        crossed = advance & (x1 * x < 0)
        t = jnp.where(advance, t1, t)
        x = jnp.where(advance, x1, x)
        return (t, x, code), (t, x, crossed, advance)

    x0 = -a0 * jnp.ones_like(model.m)
    init = (jnp.zeros_like(x0), x0, jnp.array(RESULTS.successful))
    (t, x, code), (times, positions, crossed, advanced) = lax.scan(body, init, None, length=n)
    _, _, stuck = rest(t, x)
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)


def rope_horizon(model: Rope, n: int):
    """A time by which `n` half-swings are over: 1.3 times the sum of linear half-periods
    (the longest for a hardening rope), kept short of the zero-length time."""
    life = model.lifetime()

    def body(t, _):
        half = jnp.pi / model.omega(jnp.minimum(t, 0.999 * life))
        return t + half, None

    t, _ = lax.scan(body, jnp.zeros_like(model.m), None, length=n + 1)
    return jnp.minimum(1.3 * t, 0.999 * life)


@register_solver(Rope, "exact")
def _rope_exact(model, a0, n, *, smoothing, max_substeps):
    return rope_turning_points_exact(model, a0, n, max_substeps)


@register_solver(Rope, "smooth")
def _rope_smooth(model, a0, n, *, smoothing, max_substeps):
    return turning_points_smooth(model, a0, n, smoothing, t1=rope_horizon(model, n),
                                 exhausted_code=RESULTS.length_exhausted)
