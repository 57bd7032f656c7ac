"""The exact (non-smooth) solver of decay models, half-swing by half-swing.

Within a half-swing the friction sign `s` is fixed, so the equation of motion is smooth; the
model supplies the Taylor series of its solution about any time (`model.taylor`) and a substep
well inside the series' radius of convergence (`model.substep`). The solver advances by
degree-`ORDER` Taylor polynomials, locates the velocity zero on the substep's polynomial by
bracketed Newton, and makes its time differentiable by one final Newton step taken with
gradients (the implicit-function theorem). A guard on each series' last terms turns any loss of
accuracy into a reported failure instead of a wrong answer. A fixed number of substeps per
half-swing keeps the loop shape static, so the solver runs under `jit`, `vmap` and
reverse-mode `grad`.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax

from .._models._base import AbstractDecayModel, AbstractLimitCycle
from .._numerics._series import derivative, horner
from .._solution import RESULTS
from .._numerics._scan import decay_scan
from ._base import AbstractSolver, unsupported
from .._numerics._roots import bracketed_newton, implicit_step

__all__ = ["Exact"]

ORDER = 26  #: degree of the Taylor polynomial of a substep
NEWTON = 8  #: safeguarded Newton iterations for the velocity zero
TAIL_TOLERANCE = 1e-9  #: largest relative size of a substep series' last two terms


class Exact(AbstractSolver):
    """Exact solution of the non-smooth decay: each half-swing is integrated with a fixed
    friction sign to its velocity zero by Taylor polynomials of degree 26, then the model's
    stick rule decides whether the mass stays put (real sticking, and release where the
    friction falls below the spring force).

    **Arguments:**

    - `max_substeps`: step limit per half-swing; default: the model's (8 for most models,
      where a substep is about 0.64 of a half-period for the variable-mass model; 12 for
      [`vmj.Oscillator`][], whose nonlinear laws need shorter substeps). A half-swing that
      needs more reports `RESULTS.step_limit` (overdamped or creeping motion).

    For [`vmj.limit_cycle`][], `Exact()` is the event-driven solution of the stick-slip rules.
    """

    max_substeps: int | None = eqx.field(static=True, default=None)
    name: ClassVar[str] = "exact"

    def __check_init__(self):
        if self.max_substeps is None:
            return
        if isinstance(self.max_substeps, bool) or not isinstance(self.max_substeps, int) or \
                self.max_substeps < 1:
            raise ValueError(f"max_substeps must be an integer >= 1 (got {self.max_substeps!r})")

    def check(self, model, task):
        if task == "turning_points" and isinstance(model, AbstractDecayModel):
            return model
        if task == "limit_cycle" and isinstance(model, AbstractLimitCycle):
            return model
        raise unsupported(self, model, task.replace("_", " "),
                          "use vmj.Smoothed() or the model's closed forms")

    def turning_points(self, model, a0, n: int):
        steps = model.exact_substeps if self.max_substeps is None else self.max_substeps

        def swing(t0, x0, s):
            found, limited, t1, x1 = march_to_velocity_zero(model, t0, x0, s, steps)
            return found, jnp.where(limited, model.exhausted, RESULTS.step_limit), t1, x1

        return decay_scan(model, a0, n, swing)

    def limit_cycle(self, model, max_reversals: int):
        return model.exact_cycle(max_reversals)


def march_to_velocity_zero(model, t0, x0, s, max_substeps: int):
    """From rest at `(t0, x0)` with friction sign `s`, advance by Taylor substeps to the next
    velocity zero. Returns `(found, limited, t1, x1)`: `found` is False when no velocity zero
    occurred within `max_substeps` substeps, or when a series lost accuracy (its last terms not
    negligible); `limited` tells whether the substeps were limited by the model's lifetime."""
    scale = model.swing_scale(t0, x0)
    zero = jnp.zeros_like(x0)

    def body(carry, _):
        t, x, v, found, limited, inaccurate, start = carry
        h, end_limited, t_next = model.substep(t, scale)
        cs = model.taylor(t, x, v, s, ORDER)
        x1 = horner(cs, h)
        v1 = horner(derivative(cs), h)
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
    t_guess = t0 + model.half_period(t0, scale)
    t1, x1 = _velocity_zero(model.taylor(t, x, v, s, ORDER), t, h, s, t_guess)
    return found & jnp.logical_not(inaccurate), limited, t1, x1


def _velocity_zero(cs, t, h, s, t_guess):
    """Velocity zero of the substep polynomial `cs` (Taylor coefficients about `t`, valid on
    `[t, t + h]`, moving with sign `s`): `(time, position)`."""
    dcs = derivative(cs)
    ddcs = derivative(dcs)
    f_cs = [lax.stop_gradient(c * s) for c in dcs]
    fp_cs = [lax.stop_gradient(c * s) for c in ddcs]
    hi = lax.stop_gradient(h)
    tau = jnp.clip(lax.stop_gradient(t_guess - t), 0.05 * hi, hi)
    tau = bracketed_newton(lambda x: horner(f_cs, x), lambda x: horner(fp_cs, x),
                           jnp.zeros_like(hi), hi, tau, NEWTON)
    tau = implicit_step(lambda x: horner(dcs, x), lambda x: horner(ddcs, x), tau)
    return t + tau, horner(cs, tau)
