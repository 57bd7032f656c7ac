"""Physical models. Every physical parameter is an array field, so `jax.vmap` and `jax.grad`
reach it; the equation of motion of each model is written once and shared by every solver."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from ._checks import anything, check_all, nonnegative, positive, unit_interval

__all__ = ["FrictionLaw", "Coulomb", "MassProportional", "VariableMass", "validated"]


def _float(x) -> Array:
    return jnp.asarray(x, dtype=jnp.result_type(float))


class _Checked(eqx.Module):
    """Base of every model: `_limits` maps a field name to `(predicate, allowed range)`.

    Concrete values are checked at construction (ValueError); `validated(model)` returns the
    model with `equinox.error_if` guards for traced values, and is called by every entry point.
    """

    _limits = {}

    def __check_init__(self):
        validated(self)


def validated(model):
    """Check every limited field of `model` and of the models inside it (one runtime guard for
    all traced fields); return the guarded model."""
    paths, items = [], []

    def collect(m, path):
        if isinstance(m, _Checked):
            for n, (ok, allowed) in m._limits.items():
                paths.append(path + (n,))
                items.append((n, getattr(m, n), ok, allowed))
            for n, v in vars(m).items():
                collect(v, path + (n,))

    collect(model, ())
    if not paths:
        return model

    def get(m, path):
        for n in path:
            m = getattr(m, n)
        return m

    return eqx.tree_at(lambda m: [get(m, p) for p in paths], model, check_all(items))


class FrictionLaw(_Checked):
    """Dry (Coulomb) friction law: the force magnitude as an affine function of the mass."""

    #: whether the force can change with the mass (a class constant, known when tracing)
    varies_with_mass = True

    def force(self, mass: ArrayLike) -> Array:
        """Friction force magnitude [N] when the oscillating mass is `mass` [kg]."""
        raise NotImplementedError

    def dforce_dmass(self) -> Array:
        """Derivative of the friction force with respect to the mass [N/kg]."""
        raise NotImplementedError


class Coulomb(FrictionLaw):
    """Constant dry friction force.

    **Arguments:**

    - `F`: friction force magnitude `F_T` [N], `>= 0`.
    """

    varies_with_mass = False

    F: Array = eqx.field(converter=_float)
    _limits = {"F": (nonnegative, ">= 0 [N]")}

    def force(self, mass):
        return self.F + jnp.zeros_like(mass)

    def dforce_dmass(self):
        return jnp.zeros_like(self.F)


class MassProportional(FrictionLaw):
    """Dry friction proportional to the current weight: `F(t) = f g m(t)`.

    **Arguments:**

    - `f`: sliding-friction coefficient [-], `>= 0`.
    - `g`: gravitational acceleration [m/s^2], `> 0`; 9.81 as in the paper's tables.
    """

    f: Array = eqx.field(converter=_float)
    g: Array = eqx.field(converter=_float, default=9.81)
    _limits = {"f": (nonnegative, ">= 0 [-]"), "g": (positive, "> 0 [m/s^2]")}

    def force(self, mass):
        return self.f * self.g * mass

    def dforce_dmass(self):
        return self.f * self.g


class VariableMass(_Checked):
    """Oscillator of linearly varying mass with reactive force, viscous and dry friction:

        (m0 + delta t) x'' + (delta eps + mu) x' + c x = -F(t) sign(x'),

    released from rest at `x(0) = -a0` (Olshansky & Olshansky; `SYSTEMS.md` section 1).

    **Arguments:**

    - `m0`: initial mass [kg], `> 0`.
    - `c`: spring stiffness [N/m], `> 0`.
    - `delta`: rate of change of the mass [kg/s], any sign; with `delta < 0` the mass
      vanishes at `t = m0/|delta|` and every solver stops before that.
    - `eps`: reactivity coefficient [-], in `[0, 1]` (direction of the reactive force).
    - `mu`: viscous friction coefficient [kg/s], `>= 0`.
    - `friction`: a [`vmj.Coulomb`][] (constant `F_T` [N]) or [`vmj.MassProportional`][]
      (`F = f g m(t)`) law.
    """

    m0: Array = eqx.field(converter=_float)
    c: Array = eqx.field(converter=_float)
    delta: Array = eqx.field(converter=_float)
    eps: Array = eqx.field(converter=_float)
    mu: Array = eqx.field(converter=_float)
    friction: FrictionLaw
    _limits = {
        "m0": (positive, "> 0 [kg]"),
        "c": (positive, "> 0 [N/m]"),
        "delta": (anything, "a real number [kg/s]"),
        "eps": (unit_interval, "in [0, 1]"),
        "mu": (nonnegative, ">= 0 [kg/s]"),
    }

    def __check_init__(self):
        if not isinstance(self.friction, FrictionLaw):
            raise ValueError("friction must be vmj.Coulomb(F) or vmj.MassProportional(f, g)")
        validated(self)

    # -- the equation of motion, written once -------------------------------------------------
    def mass(self, t: ArrayLike) -> Array:
        """Mass at time `t` [kg]."""
        return self.m0 + self.delta * t

    def coefficients(self, t: ArrayLike):
        """Coefficients of `m(t) x'' + b x' + c x = -F(t) sign(x')` at time `t` [s]:
        `(m, dm/dt, b, c, F, dF/dt)` in kg, kg/s, kg/s, N/m, N, N/s. Both `m` and `F` are
        affine in `t`, which the exact solver's Taylor recurrence uses."""
        m = self.mass(t)
        return (
            m,
            self.delta,
            self.delta * self.eps + self.mu,
            self.c,
            self.friction.force(m),
            self.friction.dforce_dmass() * self.delta,
        )

    def acceleration(self, t, x, v, sgn):
        """`x''` [m/s^2] at time `t` [s], position `x` [m], velocity `v` [m/s], with `sgn` standing
        for `sign(x')` (exactly +-1 in the exact solver, a smooth function in the smoothed one)."""
        m, _, b, c, F, _ = self.coefficients(t)
        return -(b * v + c * x + F * sgn) / m

    def lifetime(self) -> Array:
        """Time at which the mass would reach zero [s] (`inf` unless `delta < 0`)."""
        neg = self.delta < 0
        return jnp.where(neg, self.m0 / jnp.where(neg, -self.delta, 1.0), jnp.inf)

    def velocity_scale(self, a0) -> Array:
        """Velocity scale `a0 sqrt(c/m0)` [m/s] of a swing of amplitude `a0` [m]."""
        return a0 * jnp.sqrt(self.c / self.m0)
