"""The exact (non-smooth) solver of decay models, half-swing by half-swing.

Within a half-swing the friction sign `s` is fixed, so the equation of motion is smooth; the
model supplies the Taylor series of its solution about any time (`model.taylor`) and a substep
well inside the series' radius of convergence (`model.substep`). The solver advances by
degree-`ORDER` Taylor polynomials, locates the velocity zero on the substep's polynomial by
bracketed Newton, and makes its time differentiable by one final Newton step taken with
gradients (the implicit-function theorem). A guard on each series' last terms turns any loss of
accuracy into a reported failure instead of a wrong answer.

A substep holds the velocity zero when the velocity's sign has turned at its end or at its
middle. The end alone misses a pair of zeros: a substep that starts moving (the swing's first
fell short of the zero) and is longer than a half-period (up to `3.5/omega` for the variable
mass, whose half-period grows with the mass) can end past the next zero as well, and the swing
would skip two turning points. With the middle too, a substep shorter than twice the shortest
time between velocity zeros finds the first one (`model.substep`'s contract).

In a batch the values that several kernels read (a substep's end and its guard, Newton's value
and slope) are `computed_once`: XLA's CPU kernels would each recompute the series.

Every loop ends as soon as its work is done for every lane of a `vmap`ped batch: the substeps
when each lane has found its velocity zero (about one per half-swing), the Newton iterations
when each has converged, the swings when each has stuck or failed. Values come from plain
`lax.while_loop`s; derivatives (`jax.jacfwd`, reverse-mode `jax.grad`) from the same code with
bounded loops (`early_exit_loop`: a scan of conditionals) through a custom JVP, the same
derivatives as a fixed number of steps: a skipped step is the identity.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from equinox.internal import unvmap_any
from jax import lax

from .._checks import instance_of
from .._models._base import AbstractDecayModel, AbstractLimitCycle
from .._numerics._roots import bracketed_newton, implicit_step
from .._numerics._scan import computed_once, decay_scan, early_exit_loop, zeros_of_lanes
from .._numerics._series import derivative, horner, horner_and_derivative, slope_and_curvature
from .._solution import RESULTS
from ._base import AbstractSolver, unsupported

__all__ = ["Exact"]

ORDER = 26  #: degree of the Taylor polynomial of a substep
NEWTON = 8  #: safeguarded Newton iterations for the velocity zero
TAIL_TOLERANCE = 1e-9  #: largest relative size of a substep series' last two terms
#: a bounded (differentiable) substep loop longer than `NESTED_ABOVE` runs in nested blocks of
#: `SUBSTEP_BLOCK` substeps (the variable-mass and rope defaults, 8 and 12, stay single-level)
NESTED_ABOVE, SUBSTEP_BLOCK = 12, 8


def substep_block(max_substeps: int) -> int | None:
    """`early_exit_loop`'s `base` for a loop over at most `max_substeps` substeps: nested blocks
    of `SUBSTEP_BLOCK` above `NESTED_ABOVE`, so that its cost follows the substeps taken rather
    than the limit (a pendulum's `jax.grad` over 20 half-swings from 0.5 rad, 4 substeps each:
    19 ms at a limit of 12, 59 ms at 48 in one level; 17 ms at the oscillator's 24 in blocks of
    8); one level below."""
    return SUBSTEP_BLOCK if max_substeps > NESTED_ABOVE else None


class Exact(AbstractSolver):
    """Exact solution of the non-smooth decay: each half-swing is integrated with a fixed
    friction sign to its velocity zero by Taylor polynomials of degree 26, then the model's
    stick rule decides whether the mass stays put (real sticking, and release where the
    friction falls below the spring force).

    **Arguments:**

    - `max_substeps`: step limit per half-swing; default: the model's (8 for most models,
      where a substep is about 0.64 of a half-period for the variable-mass model; 24 for
      [`vmj.Oscillator`][], whose nonlinear laws need shorter substeps, and a pendulum released
      near the upright position more of them: up to 23 at `pi - 1e-4` rad). A half-swing that
      needs more reports `RESULTS.step_limit` (overdamped or creeping motion, or one that does
      not turn back). The loops end with the last lane's velocity zero, so a large limit
      costs little where the swings need fewer substeps (`vmj.decay_trajectory`'s table too).
    - `derivatives`: `"any"` (default): `jax.grad` (reverse mode) and `jax.jacfwd` both
      differentiate the turning points, the derivatives running every step of bounded loops.
      `"forward"`: forward mode only (`jax.jvp`, `jax.jacfwd`), through the same early-exit
      loops as the values: faster to trace, compile and run (the fits' Jacobians use it);
      reverse mode then fails with JAX's error for `lax.while_loop`.
    - `one_lane`: compile for a single solve (`vmj.turning_points` sets it for a call with
      concrete arrays): for a model whose Taylor recurrence is straight-line code
      ([`vmj.VariableMass`][]), the Newton iterations for a velocity zero recompute the
      substep's coefficients instead of carrying them into their loop. XLA's CPU backend
      makes each carried coefficient a kernel of its own (no multi-output fusion), and one
      lane pays for the number of kernels, not their size (a warm call 114-122 -> 83-88 us on
      the 2-core development machine). A batch (`vmap`, sweeps) is faster with the
      coefficients carried (the default; 4096 points: 8.8-10.5 against 12.4-13.5 ms), and so
      are models whose recurrences are loops of Cauchy products ([`vmj.Oscillator`][]: a
      warm call 590-620 against 790-830 us recomputed; [`vmj.Rope`][]: 760-890 against
      1160-1220 us).

    For [`vmj.limit_cycle`][], `Exact()` is the event-driven solution of the stick-slip rules.
    """

    max_substeps: int | None = eqx.field(static=True, default=None)
    derivatives: str = eqx.field(static=True, default="any")
    one_lane: bool = eqx.field(static=True, default=False)
    name: ClassVar[str] = "exact"

    def __check_init__(self):
        if self.derivatives not in ("any", "forward"):
            raise ValueError(f"derivatives must be 'any' or 'forward' (got {self.derivatives!r})")
        if not isinstance(self.one_lane, bool):
            raise ValueError(f"one_lane must be True or False (got {self.one_lane!r})")
        if self.max_substeps is None:
            return
        if (
            isinstance(self.max_substeps, bool)
            or not isinstance(self.max_substeps, int)
            or self.max_substeps < 1
        ):
            raise ValueError(f"max_substeps must be an integer >= 1 (got {self.max_substeps!r})")

    def check(self, model, task):
        if task == "turning_points" and instance_of(model, AbstractDecayModel):
            return model
        if task == "limit_cycle" and instance_of(model, AbstractLimitCycle):
            return model
        raise unsupported(
            self, model, task.replace("_", " "), "use vmj.Smoothed() or the model's closed forms"
        )

    def turning_points(self, model, a0, n: int):
        steps = model.exact_substeps if self.max_substeps is None else self.max_substeps
        if self.derivatives == "forward":
            return _solve_decay(model, a0, n, steps, "lax", self.one_lane)
        return _decay(model, a0, n=n, max_substeps=steps, one_lane=self.one_lane)

    def limit_cycle(self, model, max_reversals: int):
        return model.exact_cycle(max_reversals)


def _solve_decay(
    model, a0, n: int, max_substeps: int, kind: str, one_lane: bool = False, values: bool = False
):
    def swing(t0, x0, s, moving):
        found, limited, t1, x1 = march_to_velocity_zero(
            model, t0, x0, s, moving, max_substeps, kind, one_lane, values
        )
        return found, jnp.where(limited, model.exhausted, RESULTS.step_limit), t1, x1

    return decay_scan(model, a0, n, swing, kind)


@eqx.filter_custom_jvp
def _decay(model, a0, *, n: int, max_substeps: int, one_lane: bool):
    """The decay with plain `lax.while_loop`s (the fastest loops, not reverse-differentiable);
    derivatives, forward or reverse, come from the same code with bounded loops (below)."""
    return _solve_decay(model, a0, n, max_substeps, "lax", one_lane, values=not one_lane)


@_decay.def_jvp
def _decay_jvp(primals, tangents, *, n: int, max_substeps: int, one_lane: bool):
    return eqx.filter_jvp(
        lambda m, a: _solve_decay(m, a, n, max_substeps, "bounded", one_lane), primals, tangents
    )


def march_to_velocity_zero(
    model,
    t0,
    x0,
    s,
    moving,
    max_substeps: int,
    kind: str,
    one_lane: bool = False,
    values: bool = False,
):
    """From rest at `(t0, x0)` with friction sign `s`, advance by Taylor substeps to the next
    velocity zero (lanes with `moving` False take no substep). Returns `(found, limited, t1,
    x1)`: `found` is False when no velocity zero occurred within `max_substeps` substeps, or
    when a series lost accuracy (its last terms not negligible); `limited` tells whether the
    substeps were limited by the model's lifetime. The substeps end as soon as every lane of a
    `vmap`ped batch has found its zero (`kind`: of `early_exit_loop`; `one_lane`: as in
    `Exact`). With `values` (a batch's solve that is not differentiated) the first substep runs
    before the loop and Newton takes its series: almost every swing's zero is in it, and the series
    was computed again for Newton (211 of a half-swing's operations for the variable mass; now
    only where a later substep holds the zero, under a conditional that a batch skips when no
    lane needs it). Derivatives keep the substep in the loop alone: their programs would hold
    its code twice (`jax.jacfwd` of 12 swings compiled in 4.1 -> 7.4 s); so does a single solve
    (`one_lane`), whose time is its kernels' number (a repeated `vmj table 1` took 0.78 ->
    0.88 s with it)."""
    scale = model.swing_scale(t0, x0)
    zero = zeros_of_lanes(x0)

    def cond(carry):
        k, found = carry[0], carry[4]
        return (k < max_substeps) & unvmap_any(jnp.logical_not(found))

    def step(k, t, x, v, found, limited, inaccurate, start):
        """One substep: the carry after it, and its series."""
        h, end_limited, t_next = model.substep(t, scale)
        cs = model.taylor(t, x, v, s, ORDER)
        # truncation guard: the last terms of the series must be negligible (a diverging
        # series is off by orders of magnitude; accurate ones stay near 1e-13 or far below)
        n = len(cs) - 1
        tail = jnp.abs(cs[-1]) * h**n + jnp.abs(cs[-2]) * h ** (n - 1)
        x1, v1 = horner_and_derivative(cs, h)
        # the velocity's sign at mid-substep too (module docstring: two zeros in one substep)
        v_mid = horner(derivative(cs), 0.5 * h)
        if not one_lane:  # (a batch: each of the four would recompute the series)
            x1, v1, tail, v_mid = computed_once((x1, v1, tail, v_mid), k)
        bad = tail > TAIL_TOLERANCE * (jnp.abs(x) + jnp.abs(x1) + jnp.abs(v) * h)
        inaccurate = inaccurate | (bad & jnp.logical_not(found))
        early = v_mid * s <= 0  # (the first zero in the substep's first half)
        hit = jnp.logical_not(found) & (early | (v1 * s <= 0))
        # the substep holding the zero: its start, length (its first half for an early zero)
        # and series
        held = (t, x, v, jnp.where(early, 0.5 * h, h))
        start = jax.tree.map(lambda new, old: jnp.where(hit, new, old), held, start)
        limited = jnp.where(found, limited, end_limited)
        found = found | hit
        t, x, v = (jnp.where(found, a, b) for a, b in ((t, t_next), (x, x1), (v, v1)))
        return (k + 1, t, x, v, found, limited, inaccurate, start), cs

    false = zeros_of_lanes(x0, bool)
    # (outside a loop the counter is made opaque to XLA, which would fold `computed_once`'s
    # conditional away)
    k0 = lax.optimization_barrier(jnp.array(0)) if values else jnp.array(0)
    init = (k0, t0, x0, zero, jnp.logical_not(moving), false, false, (t0, x0, zero, zero))
    first, cs = step(*init) if values else (init, None)
    _, reached, _, _, found, limited, inaccurate, (t, x, v, h) = early_exit_loop(
        cond,
        lambda carry: step(*carry)[0],
        first,
        max_substeps,
        kind=kind,
        base=substep_block(max_substeps),
    )
    if values:
        _, _, _, _, found_first, *_ = first
        later = found & jnp.logical_not(found_first)  # (lanes whose zero a later substep holds)
        cs = lax.cond(
            unvmap_any(later),
            lambda c: [jnp.where(later, a, b) for a, b in zip(model.taylor(t, x, v, s, ORDER), c)],
            lambda c: c,
            cs,
        )
    else:
        cs = model.taylor(t, x, v, s, ORDER)
    # substeps that crowd against the model's lifetime (a rope's length running out, whose
    # substeps shrink with it) end the model, not the step budget
    limited = limited | (lax.stop_gradient(reached) >= (1 - 1e-6) * model.lifetime())
    t_guess = t0 + model.half_period(t0, scale)
    t1, x1 = _velocity_zero(model, cs, t, x, v, s, h, t_guess, one_lane)
    # a zero whose Newton iterations broke down (a velocity that only touches zero, or a
    # series next to the zero-mass singularity) is no turning point: it was counted with NaN
    # time and position (a creeping mass-proportional friction with --max-substeps 200)
    ok = jnp.isfinite(t1) & jnp.isfinite(x1)
    return found & jnp.logical_not(inaccurate) & ok, limited, t1, x1


def _velocity_zero(model, cs, t, x, v, s, h, t_guess, one_lane: bool):
    """Velocity zero of the substep's Taylor polynomial `cs` about `(t, x, v)` (valid on
    `[t, t + h]`, moving with sign `s`): `(time, position)`. Newton's iterations use the
    series' coefficients carried into their loop, or recomputed in it with `one_lane` (for a
    model with a straight-line recurrence)."""
    if one_lane and model.straight_line_taylor:
        stopped = lax.stop_gradient((model, t, x, v))
        series = lambda: stopped[0].taylor(*stopped[1:], s, ORDER)  # noqa: E731
    else:
        stopped = lax.stop_gradient(cs)
        series = lambda: stopped  # noqa: E731

    def velocity(y):  # (s v, s dv/dt) at t + y, from the position's coefficients (their
        # derivative's, loop-invariant, would be made before the loop, a kernel each)
        value, slope = slope_and_curvature(series(), y)
        return s * value, s * slope

    hi = lax.stop_gradient(h)
    tau = jnp.clip(lax.stop_gradient(t_guess - t), 0.05 * hi, hi)
    tau = bracketed_newton(velocity, zeros_of_lanes(hi), hi, tau, NEWTON, batch=not one_lane)
    tau = implicit_step(lambda y: horner_and_derivative(derivative(cs), y), tau)
    return t + tau, horner(cs, tau)
