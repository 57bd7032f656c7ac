"""Energy-balance half-swing maps of [`vmj.Oscillator`][] (classical results, no single source
paper). With `W(x) = V(x) + s xF x` the potential of the restoring law plus the work of the dry
friction during a half-swing of velocity sign `s` (per unit mass, divided by `omega^2`):

- dry friction only, any restoring law: the exact map `W(x_k) = W(x_{k+1})`, i.e.
  `V(x_k) - V(x_{k+1}) = xF |x_k - x_{k+1}|`, solved per swing by the shared root finder; the
  half-swing time is the energy integral `int dx / |v|` with
  `v^2 = 2 omega^2 (x - r1)(r2 - x) V[r1, r2, x]` (`V[.,.,.]` the second divided difference),
  evaluated by the rope's swing quadrature (exact to rounding);
- linear restoring law with viscous damping and dry friction: the exact closed form
  `x_{k+1} = -s xF - rho (x_k + s xF)`, `rho = exp(-zeta omega pi/omega_d)`, in the time
  `pi/omega_d`, `omega_d = omega sqrt(1 - zeta^2)`;
- otherwise (viscous or quadratic damping with a nonlinear restoring law, quadratic drag with
  any law) an averaged map: the energy lost to the speed-dependent laws is evaluated on the
  chord swing between `x_k` and `x_{k+1}` (the dry-friction swing's speed profile with its end
  moved to `x_{k+1}`) and `W(x_k) - W(x_{k+1}) = loss(x_k, x_{k+1}) / omega^2` is solved for
  `x_{k+1}`. Linear viscous damping gives `(1 - pi zeta/2)/(1 + pi zeta/2)` for
  `exp(-pi zeta)`: the amplitude error is `O(zeta^3)` per half-swing, the time error
  `O(zeta^2)`. It reduces to the exact map when the speed-dependent coefficients vanish.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from .._laws._dissipation import ViscousDamping
from .._laws._restoring import LinearRestoring
from .._numerics._roots import bracketed_newton, expanding_root, implicit_step
from .._numerics._scan import decay_scan
from .._solution import RESULTS
from ._osinski import swing_nodes

__all__ = ["energy_map_sequence", "chord_swing"]

NEWTON = 30  #: safeguarded Newton iterations of the averaged map's end point


def chord_swing(law, omega, r1, r2):
    """The swing between turning points `r1 < r2` whose kinetic energy per unit mass is
    `omega^2 (x - r1)(r2 - x) V[r1, r2, x]`: quadrature nodes `x`, their weights in position
    `dx`, the speed `|v|` there, and the duration [s]. (`V[r1, r2, x] > 0` on a real swing; on
    the trial swings of a root search it may not be, and counts as 0.)"""
    x, w, cos = swing_nodes(r1, r2)
    half = 0.5 * (r2 - r1)
    q = (law.chord(x, r1 - x) - law.chord(x, r2 - x)) / (r1 - r2)  # V[r1, r2, x]
    # (the square root and its reciprocal of positive q only: at q <= 0, with 0 and inf taken
    # as constants, their infinite derivatives meet no zero cotangent, which made reverse-mode
    # gradients NaN through a swing that was discarded, e.g. a pendulum stuck at the release)
    real = q > 0
    root = jnp.sqrt(jnp.where(real, 2 * q, 1.0))
    time = jnp.sum(jnp.where(real, w / root, jnp.inf)) / omega
    return x, w * half * cos, omega * half * cos * jnp.where(real, root, 0.0), time


def _dry_turning_point(law, x, s, kinetic):
    """The next turning point from rest at `x` under dry friction only: `(x1, bounded)`."""

    def g(y):  # (W(x) - W(x + s y)) / y: positive until the turning point
        return -s * law.chord(x, s * y) - kinetic

    y, bounded = expanding_root(g, 2 * jnp.abs(x))
    return x + s * y, bounded


def _averaged_end(model, x, s, xc, kinetic, drag):
    """The end `x1 = xc - s delta` of a half-swing from `x` whose dry-friction end is `xc`, from
    `W(x) - W(x1) = loss / omega^2`: `(x1, found)` (`found` False when the loss would stop the
    swing before its middle: overdamped)."""
    law, omega = model.restoring, model.omega

    def f(delta):  # > 0 from delta = 0 (loss) until the balance holds
        x1 = xc - s * delta
        nodes, dx, speed, _ = chord_swing(law, omega, jnp.minimum(x, x1), jnp.maximum(x, x1))
        loss = sum(d.swing_loss(omega, nodes, speed, dx, s) for d in drag) / (omega * omega)
        return loss - delta * (s * law.chord(xc, -s * delta) + kinetic)

    fs = lambda d: lax.stop_gradient(f(d))  # noqa: E731
    fp = lambda d: lax.stop_gradient(jax.grad(f)(d))  # noqa: E731
    hi = lax.stop_gradient(0.5 * jnp.abs(xc - x))
    slope = jnp.maximum(s * law.value(xc) + kinetic, 1e-300)
    guess = jnp.clip(fs(jnp.zeros_like(hi)) / lax.stop_gradient(slope), 0.0, hi)
    delta = bracketed_newton(lambda d: (fs(d), fp(d)), jnp.zeros_like(hi), hi, guess, NEWTON)
    delta = implicit_step(lambda d: (f(d), jax.grad(f)(d)), delta)
    return xc - s * delta, fs(hi) <= 0


def energy_map_sequence(model, a0, n: int):
    """The first `n` turning points of `model` from its half-swing energy map (module
    docstring), with the model's stick rule at each turning point."""
    law, omega = model.restoring, model.omega
    kinetic, _ = model.levels()
    drag = [d for d in model.dissipation if d.velocity_dependent]
    closed = isinstance(law, LinearRestoring) and all(isinstance(d, ViscousDamping) for d in drag)

    if closed:
        zeta = sum((d.zeta for d in drag), jnp.zeros_like(omega))
        under = zeta < 1
        wd = omega * jnp.sqrt(jnp.where(under, 1 - zeta * zeta, 1.0))
        half = jnp.pi / wd
        rho = jnp.exp(-zeta * omega * half)

        def swing(t, x, s, moving):
            return under, RESULTS.step_limit, t + half, -s * kinetic - rho * (x + s * kinetic)

        return decay_scan(model, a0, n, swing)

    def swing(t, x, s, moving):
        x1, bounded = _dry_turning_point(law, x, s, kinetic)
        found = bounded
        if drag:
            x1, ok = _averaged_end(model, x, s, x1, kinetic, drag)
            found = found & ok
        time = chord_swing(law, omega, jnp.minimum(x, x1), jnp.maximum(x, x1))[3]
        finite = jnp.isfinite(time)  # (a swing at the separatrix: its quadrature diverges)
        code = jnp.where(
            bounded, jnp.where(finite, RESULTS.step_limit, RESULTS.map_diverged), RESULTS.unbounded
        )
        return found & finite, code, t + time, x1

    return decay_scan(model, a0, n, swing)
