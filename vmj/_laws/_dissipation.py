"""Dissipation laws of [`vmj.Oscillator`][]: forces per unit mass (or inertia) that oppose the
motion, written with the oscillator's small-amplitude natural frequency `omega` [rad/s] so
that their coefficients are dimensionless or positions (`zeta`, `xF`, `cq`).

A law provides its force (`sgn` stands for the sign of the velocity: exactly +-1 in the exact
solver, `tanh(v/w)` in the smoothed one), its smoothed force, the Taylor coefficient of its
force within a half-swing (fixed sign `s`, built from the series of `x(t)` and `v(t)`), a bound
on the radius of convergence it imposes, its dry-friction levels and its energy loss over a
half-swing (the energy balance).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array

from .._checks import AbstractParams, _float, nonnegative
from .._numerics._series import cauchy_term

__all__ = ["DissipationLaw", "ViscousDamping", "CoulombDamping", "QuadraticDamping"]

STRIBECK = 7.0  #: velocity width of the smoothed static level, in smoothing velocities w


class DissipationLaw(AbstractParams):
    """A force per unit mass `D(x, v)` [position unit/s^2] on the left-hand side of
    `x'' + sum D + omega^2 r(x) = 0`."""

    #: whether the force depends on the speed (False for dry friction, which the energy
    #: balance treats exactly)
    velocity_dependent: ClassVar[bool] = True

    @abc.abstractmethod
    def force(self, omega, x, v, sgn) -> Array:
        """`D` at position `x`, velocity `v`, with `sgn` standing for `sign(v)`."""

    @abc.abstractmethod
    def series_term(self, omega, n, xs, vs, s) -> Array:
        """Coefficient `n` (traced) of the Taylor series of `D(x(t), v(t))` within a
        half-swing of velocity sign `s`, given the series `xs` of `x` and `vs` of `v`
        (entries up to `n` filled)."""

    def smoothed_force(self, omega, x, v, w) -> Array:
        """`D` with `sign(v)` replaced by `tanh(v/w)`, `w` the smoothing velocity."""
        return self.force(omega, x, v, jnp.tanh(v / w))

    def radius(self, omega, vmax) -> Array:
        """A lower bound [s] on the radius of convergence of the Taylor series of a half-swing
        at speeds up to `vmax`, as far as this law is concerned (`inf`: no limit)."""
        return jnp.full_like(jnp.asarray(vmax, dtype=float), jnp.inf)

    def levels(self):
        """Dry-friction levels `(kinetic, static)` as dead-band positions [position unit]."""
        return 0.0, 0.0

    def swing_loss(self, omega, x, speed, dx, s) -> Array:
        """Energy per unit mass dissipated over a half-swing of velocity sign `s` whose speed
        `|v|` at the quadrature nodes `x` (weights `dx`, in position) is `speed`
        [position unit^2/s^2]: the work `sum dx s D(x, s |v|, s)`."""
        return jnp.sum(dx * s * self.force(omega, x, s * speed, s))


class ViscousDamping(DissipationLaw):
    """Linear viscous damping, `D = 2 zeta omega v`.

    **Arguments:**

    - `zeta`: damping ratio [-], `>= 0` (the motion is oscillatory for `zeta < 1`).
    """

    zeta: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {"zeta": (nonnegative, ">= 0 [-]")}

    def force(self, omega, x, v, sgn):
        return 2 * self.zeta * omega * v

    def series_term(self, omega, n, xs, vs, s):
        return 2 * self.zeta * omega * vs[n]

    def radius(self, omega, vmax):
        # the damped motion is entire; its terms (lambda h)^n/n! decay fast while the largest
        # rate, about 2 zeta omega when overdamped, times the substep stays below 2. Near
        # critical damping the half-swing pi/omega_d (omega_d = omega sqrt(1 - zeta^2)) grows
        # without bound: the bound is raised so that 20 substeps (0.3 of it each) span it,
        # within the default limit of 24 and never beyond the undamped substep 3.5/omega
        # (the rates' modulus is omega while underdamped). Until 2026-11-28 a half-swing
        # needed more than 24 substeps from zeta = 0.985 on and reported a step limit; now
        # up to zeta = 0.999 (turning points within 1e-13 of a0 and times within 4e-11
        # relative of the closed form, vmj.EnergyBalance's).
        under = self.zeta < 1
        damped = omega * jnp.sqrt(jnp.where(under, 1 - self.zeta**2, 1.0))
        span = jnp.where(under, jnp.pi / (20 * 0.3) / damped, 0.0)
        return jnp.maximum(3.0 / (self.zeta * omega), span) + 0 * vmax


class QuadraticDamping(DissipationLaw):
    """Quadratic (aerodynamic) drag, `D = cq v |v|`.

    **Arguments:**

    - `cq`: drag coefficient [1/position unit] (1/rad for a pendulum), `>= 0`. For a body in
      air `cq = rho C_d A r_p / (2 m)` with `r_p` the lever arm of the drag (per unit length of
      the swing coordinate).
    """

    cq: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {"cq": (nonnegative, ">= 0 [1/position unit]")}

    def force(self, omega, x, v, sgn):
        return self.cq * v * jnp.abs(v)

    def series_term(self, omega, n, xs, vs, s):
        return self.cq * s * cauchy_term(vs, vs, n)  # v|v| = s v^2 within a half-swing

    def radius(self, omega, vmax):
        # measured (root test) for the linear spring: the radius is above ln(1 + omega/(cq v))
        # / omega, which tends to the pole 1/(cq v) of v' = -cq v^2 for strong drag
        return jnp.log1p(omega / (self.cq * vmax)) / omega


class CoulombDamping(DissipationLaw):
    """Dry (Coulomb) friction as a dead band: `D = omega^2 xF sign(v)`; at a turning point the
    mass sticks for good while `|r(x)| <= xS` (the restoring force is at most the static
    friction).

    **Arguments:**

    - `xF`: kinetic friction level as a position (the half-width of the dead band) [position
      unit; rad for a pendulum], `>= 0`. The friction force is `m omega^2 xF`.
    - `xS`: static friction level [position unit], `>= xF`; default `xF`. Where a decay stops
      tells it.

    In the smoothed ODE the static level is the friction's limit at small speed: the force
    is `omega^2 (xF + (xS - xF) exp(-(v/(7 w))^8)) tanh(v/w)`, whose maximum over `v` is
    `xF + 0.995 (xS - xF)` (a mass whose `|r(x)|` is that close below `xS` slips in the
    smoothed model).
    """

    velocity_dependent: ClassVar[bool] = False

    xF: Array
    xS: Array
    _limits: ClassVar[dict] = {
        "xF": (nonnegative, ">= 0 [position unit]"),
        "xS": (nonnegative, ">= xF [position unit]"),
    }
    _relations: ClassVar[dict] = {"xS": (lambda law: law.xS >= law.xF, ">= xF [position unit]")}

    def __init__(self, xF, xS=None):
        self.xF = _float(xF)
        self.xS = self.xF if xS is None else _float(xS)

    def force(self, omega, x, v, sgn):
        return omega * omega * self.xF * sgn

    def smoothed_force(self, omega, x, v, w):
        static = jnp.exp(-((v / (STRIBECK * w)) ** 8))
        return omega * omega * (self.xF + (self.xS - self.xF) * static) * jnp.tanh(v / w)

    def series_term(self, omega, n, xs, vs, s):
        return jnp.where(n == 0, omega * omega * self.xF * s, 0.0)

    def levels(self):
        return self.xF, self.xS
