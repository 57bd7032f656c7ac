"""The variable-mass oscillator with reactive force, viscous and dry friction
(Olshansky & Olshansky; `SYSTEMS.md` section 1)."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._checks import _float, anything, nonnegative, positive, unit_interval
from .._closed_forms._olshansky import energy_balance_sequence
from .._laws._friction import FrictionLaw
from ._base import AbstractEnergyMap

__all__ = ["VariableMass"]

#: substep length in units of 1/(sqrt(c/m) + b/m), the fastest local rate: a half-swing of
#: pi/omega in one substep (the series' last two terms at omega h = 3.5 are 3e-12 of the
#: amplitude, against the truncation guard's 1e-9; the exact sweep of 4096 random points took
#: 2.0 substeps per half-swing at 2.0, 1.0 now: 0.73-0.83 x its time)
RHO_OMEGA = 3.5
RHO_MASS = 0.25  #: substep length as a fraction of m(t)/|dm/dt|


class VariableMass(AbstractEnergyMap):
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
    _limits: ClassVar[dict] = {
        "m0": (positive, "> 0 [kg]"),
        "c": (positive, "> 0 [N/m]"),
        "delta": (anything, "a real number [kg/s]"),
        "eps": (unit_interval, "in [0, 1] [-]"),
        "mu": (nonnegative, ">= 0 [kg/s]"),
    }

    def __check_init__(self):
        if not isinstance(self.friction, FrictionLaw):
            raise ValueError(
                "friction must be a friction law: vmj.Coulomb(F), "
                "vmj.MassProportional(f, g) or vmj.AffineFriction(FT, f, g)"
            )

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

    lifetime_text: ClassVar[str] = "the zero-mass time m0/|delta|"

    # -- the exact solver's half-swing ----------------------------------------------------------
    straight_line_taylor: ClassVar[bool] = True  # (the three-term recurrence below)

    def rest(self, t, x):
        """At rest at `(t, x)`: the spring force `c|x|` moves the mass when it exceeds the
        friction `F(t)`; friction that falls with time (mass-proportional friction and a
        shrinking mass) releases a stuck mass when it has fallen below the spring force."""
        _, _, _, c, F, Fd = self.coefficients(t)
        spring = c * jnp.abs(x)
        moves = spring > F
        decreasing = Fd < 0
        t_release = t + (F - spring) / jnp.where(decreasing, -Fd, 1.0)
        release = jnp.logical_not(moves) & decreasing
        return -jnp.sign(x), jnp.where(release, t_release, t), jnp.logical_not(moves | release)

    def swing_scale(self, t, x):
        return jnp.abs(x)

    def taylor(self, t, x, v, s, order: int):
        """Within a half-swing `m(t) x'' + b x' + c x = -s F(t)` is linear with `m` and `F`
        affine in `t`: its Taylor coefficients obey a three-term recurrence."""
        m, md, b, c, F, Fd = self.coefficients(t)
        inv_m = 1.0 / m
        xs = [x, v]
        for n in range(order - 1):
            rhs = c * xs[n] + (n + 1) * (md * n + b) * xs[n + 1]
            if n == 0:
                rhs = rhs + s * F
            elif n == 1:
                rhs = rhs + s * Fd
            # (a multiplication by the reciprocal: a division here costs as much as the rest)
            xs.append(rhs * (inv_m * (-1.0 / ((n + 2) * (n + 1)))))
        return xs

    def substep(self, t, scale):
        """At most `RHO_OMEGA / (sqrt(c/m) + b/m)` (the local eigenvalues) and `RHO_MASS`
        times the distance `m/|dm/dt|` to the zero-mass singularity."""
        m, md, b, c, *_ = self.coefficients(t)
        inv_m = 1.0 / m
        h_omega = RHO_OMEGA / (jnp.sqrt(c * inv_m) + jnp.abs(b) * inv_m)
        amd = jnp.abs(md)
        has_rate = amd > 0
        h_mass = jnp.where(has_rate, RHO_MASS * m / jnp.where(has_rate, amd, 1.0), jnp.inf)
        h = jnp.minimum(h_omega, h_mass)
        # limited by the approach of the zero-mass time only while the mass falls: a growing
        # mass that runs out of steps has not been exhausted (it is reported as the step limit)
        return h, (h_mass < h_omega) & (md < 0), t + h

    def half_period(self, t, scale):
        """Damped half-period with the mass at mid-swing [s]."""
        m, md, b, c, *_ = self.coefficients(t)
        m = jnp.maximum(m + 0.5 * md * jnp.pi * jnp.sqrt(m / c), 0.5 * m)
        omega2 = jnp.maximum(c / m - (b / (2 * m)) ** 2, 0.25 * c / m)
        return jnp.pi / jnp.sqrt(omega2)

    # -- the paper's energy-balance recurrences -------------------------------------------------
    def energy_map(self, a0, n: int):
        """The paper's recurrences (11)-(13), (13) as corrected in `SYSTEMS.md`."""
        return energy_balance_sequence(self, a0, n)
