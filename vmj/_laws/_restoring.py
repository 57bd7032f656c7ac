"""Restoring laws of [`vmj.Oscillator`][]: the spring (or gravity) term `omega^2 r(x)` of
`x'' + ... + omega^2 r(x) = 0`, with `r'(0) = 1` so that `omega` is the small-amplitude natural
frequency.

A law provides what each solver needs: its value `r(x)` and tangent stiffness `r'(x)` (the
smoothed ODE), its potential `V(x)` with `V' = r` and the chord slope of `V` (the energy
balance), the Taylor series of `r(x(t))` built one coefficient at a time from the series of
`x(t)` (the exact solver), a lower bound on that series' radius of convergence (the exact
solver's substep) and an estimate of the frequency of a swing (starting guesses).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array

from .._checks import AbstractParams, _float, anything, unit_interval
from .._numerics._series import cauchy_term

__all__ = ["RestoringLaw", "LinearRestoring", "PolynomialRestoring", "SineRestoring"]


class RestoringLaw(AbstractParams):
    """A restoring law `r(x)` with `r(0) = 0`, `r'(0) = 1`; `x` in the oscillator's position
    unit (rad for angular laws)."""

    #: whether `x` is an angle in radians (for messages and documentation)
    angular: ClassVar[bool] = False

    @abc.abstractmethod
    def value(self, x) -> Array:
        """`r(x)` [position unit]."""

    @abc.abstractmethod
    def stiffness(self, x) -> Array:
        """Tangent stiffness `r'(x)` [-]."""

    @abc.abstractmethod
    def potential(self, x) -> Array:
        """`V(x) = int_0^x r` [position unit^2]."""

    @abc.abstractmethod
    def chord(self, x, z) -> Array:
        """Slope of the chord of the potential, `(V(x + z) - V(x)) / z` (`r(x)` at `z = 0`),
        evaluated without cancellation [position unit]."""

    @abc.abstractmethod
    def series_start(self, x0, k: int):
        """Working arrays of the Taylor recurrence (`k` coefficients) about a point `x0`."""

    @abc.abstractmethod
    def series_term(self, n, xs, work):
        """Coefficient `n` (traced) of the Taylor series of `r(x(t))`, given the coefficients
        `xs[0..n]` of `x(t)` (later entries zero): `(r_n, work)`."""

    @abc.abstractmethod
    def radius(self, a) -> Array:
        """A lower bound on the radius of convergence of the Taylor series of a swing of
        amplitude `a`, in units of `1/omega` (`inf` when the solution is entire)."""

    @abc.abstractmethod
    def frequency(self, a) -> Array:
        """Estimated angular frequency of a frictionless swing of amplitude `a`, in units of
        `omega` (1 for small amplitude)."""

    def stiffness_bound(self, a) -> Array:
        """An upper bound on the tangent stiffness `|r'(x)|` for `|x| <= a` (sizes the exact
        solver's substeps through `radius`)."""
        return jnp.ones_like(jnp.asarray(a, dtype=float))


class LinearRestoring(RestoringLaw):
    """The linear spring, `r(x) = x`. No parameters."""

    def value(self, x):
        return x

    def stiffness(self, x):
        return jnp.ones_like(x)

    def potential(self, x):
        return 0.5 * x * x

    def chord(self, x, z):
        return x + 0.5 * z

    def series_start(self, x0, k):
        return ()

    def series_term(self, n, xs, work):
        return xs[n], work

    def radius(self, a):
        return jnp.full_like(jnp.asarray(a, dtype=float), jnp.inf)

    def frequency(self, a):
        return jnp.ones_like(jnp.asarray(a, dtype=float))


# -- the polynomial terms b2 x^2 + b3 x^3, shared by the polynomial and the sine laws -----------
def _cubic(law, x):
    return x * x * (law.b2 + law.b3 * x)


def _cubic_stiffness(law, x):
    return x * (2 * law.b2 + 3 * law.b3 * x)


def _cubic_potential(law, x):
    return x * x * x * (law.b2 / 3 + law.b3 * x / 4)


def _cubic_chord(law, x, z):
    """`(P(x + z) - P(x)) / z` for `P = b2 x^3/3 + b3 x^4/4`, expanded (no cancellation)."""
    return (
        law.b2 * (3 * x * x + 3 * x * z + z * z) / 3
        + law.b3 * (4 * x**3 + 6 * x * x * z + 4 * x * z * z + z**3) / 4
    )


def _cubic_term(law, n, xs, x2):
    """Coefficient `n` of `b2 x^2 + b3 x^3` by Cauchy products (`x2` holds those of `x^2`)."""
    x2 = x2.at[n].set(cauchy_term(xs, xs, n))
    return law.b2 * x2[n] + law.b3 * cauchy_term(x2, xs, n), x2


def _cubic_bound(law, a):
    a = jnp.abs(a)
    return 1 + 2 * jnp.abs(law.b2) * a + 3 * jnp.abs(law.b3) * a * a


def _cubic_modulus(law, a):
    """The elliptic modulus `k` that the polynomial terms give a swing of amplitude `a`, for the
    series radius: `|b3| a^2 / 2` is the Duffing solution's `k^2`; the quadratic term's poles
    (a Weierstrass function) lie about `ln(1/(|b2| a)) + 2` away (measured from the series'
    root test for `|b2| a` in [0.002, 0.5]), more than `ln(4/(|b2| a))`: the two terms' `k`
    added."""
    return (jnp.abs(law.b2) + jnp.sqrt(0.5 * jnp.abs(law.b3))) * jnp.abs(a)


def _cubic_frequency(law, a):
    """Lindstedt's first-order frequency factor `1 + 3 b3 a^2/8 - 5 b2^2 a^2/12`, written as a
    square root that stays positive (and is close to exact for a stiff cubic)."""
    return jnp.sqrt(jnp.maximum(1 + 0.75 * law.b3 * a * a - (5 / 6) * (law.b2 * a) ** 2, 0.1))


_CUBIC_LIMITS = {
    "b2": (anything, "a real number [1/position unit]"),
    "b3": (anything, "a real number [1/position unit^2]"),
}


class PolynomialRestoring(RestoringLaw):
    """A polynomial spring `r(x) = x + b2 x^2 + b3 x^3` (the family of the rope's `e, b, d`).

    **Arguments:**

    - `b2`: quadratic coefficient [1/position unit], any sign (an asymmetric spring).
    - `b3`: cubic coefficient [1/position unit^2]: `> 0` hardening, `< 0` softening.

    A softening or asymmetric spring has a potential barrier: a swing above it has no turning
    point (the solvers report it).
    """

    b2: Array = eqx.field(converter=_float, default=0.0)
    b3: Array = eqx.field(converter=_float, default=0.0)
    _limits: ClassVar[dict] = _CUBIC_LIMITS

    def value(self, x):
        return x + _cubic(self, x)

    def stiffness(self, x):
        return 1 + _cubic_stiffness(self, x)

    def potential(self, x):
        return 0.5 * x * x + _cubic_potential(self, x)

    def chord(self, x, z):
        return x + 0.5 * z + _cubic_chord(self, x, z)

    def series_start(self, x0, k):
        return jnp.zeros(k, dtype=jnp.result_type(x0, self.b3))

    def series_term(self, n, xs, work):
        extra, work = _cubic_term(self, n, xs, work)
        return xs[n] + extra, work

    def radius(self, a):
        # the Duffing solution a cn(Omega t, k) has its poles at distance K'(k)/Omega >
        # max(pi/2, ln(4/k))/Omega from the real axis, over the root of the stiffness bound
        k = jnp.maximum(_cubic_modulus(self, a), 1e-300)
        return jnp.maximum(0.5 * jnp.pi, jnp.log(4 / k)) / jnp.sqrt(self.stiffness_bound(a))

    def frequency(self, a):
        return _cubic_frequency(self, a)

    def stiffness_bound(self, a):
        return _cubic_bound(self, a)


class SineRestoring(RestoringLaw):
    """The pendulum, `r(x) = w sin(x) + (1 - w) x + b2 x^2 + b3 x^3`, `x` the angle [rad] from
    the hanging position and `omega = sqrt(g/l)` (`sqrt(m g d / J)` for a physical pendulum)
    [rad/s].

    **Arguments:**

    - `b2`: quadratic correction [1/rad], default 0 (an asymmetric restoring torque).
    - `b3`: cubic correction [1/rad^2], default 0 (a restoring law between the sine and the
      linear one, or stiffer, as measured large-angle data may ask for).
    - `w`: the sine's share of the restoring torque [-], in `[0, 1]`, default 1 (gravity
      alone). A pendulum whose pivot also has a torsional stiffness `k` has
      `w = m g d / (m g d + k)` (and `omega^2 = (m g d + k) / J`); `w = 0` is the linear
      (polynomial) law.
    """

    angular: ClassVar[bool] = True

    b2: Array = eqx.field(converter=_float, default=0.0)
    b3: Array = eqx.field(converter=_float, default=0.0)
    w: Array = eqx.field(converter=_float, default=1.0)
    _limits: ClassVar[dict] = {
        "b2": (anything, "a real number [1/rad]"),
        "b3": (anything, "a real number [1/rad^2]"),
        "w": (unit_interval, "in [0, 1] [-]"),
    }

    def value(self, x):
        return self.w * jnp.sin(x) + (1 - self.w) * x + _cubic(self, x)

    def stiffness(self, x):
        return self.w * jnp.cos(x) + (1 - self.w) + _cubic_stiffness(self, x)

    def potential(self, x):
        return (
            self.w * 2 * jnp.sin(0.5 * x) ** 2
            + (1 - self.w) * 0.5 * x * x
            + _cubic_potential(self, x)
        )

    def chord(self, x, z):
        # (cos x - cos(x + z)) / z = sin(x + z/2) sinc(z/2)
        sine = jnp.sin(x + 0.5 * z) * jnp.sinc(z / (2 * jnp.pi))
        return self.w * sine + (1 - self.w) * (x + 0.5 * z) + _cubic_chord(self, x, z)

    def series_start(self, x0, k):
        zeros = jnp.zeros(k, dtype=jnp.result_type(x0, self.b3))
        return zeros.at[0].set(jnp.sin(x0)), zeros.at[0].set(jnp.cos(x0)), zeros

    def series_term(self, n, xs, work):
        """`s_n = (1/n) sum_j j x_j c_{n-j}`, `c_n = -(1/n) sum_j j x_j s_{n-j}` for the series
        `s`, `c` of `sin(x(t))`, `cos(x(t))`."""
        s, c, x2 = work
        jx = jnp.arange(xs.shape[0]) * xs
        m = jnp.maximum(n, 1)
        s = s.at[n].set(jnp.where(n == 0, s[0], cauchy_term(jx, c, n) / m))
        c = c.at[n].set(jnp.where(n == 0, c[0], -cauchy_term(jx, s, n) / m))
        extra, x2 = _cubic_term(self, n, xs, x2)
        return self.w * s[n] + (1 - self.w) * xs[n] + extra, (s, c, x2)

    def radius(self, a):
        # x = 2 arcsin(k sn(omega t, k)), k = sin(a/2), is singular at distance K'(k)/omega from
        # the real axis, and K'(k) > max(pi/2, ln(4/k)); a share w of the sine is a softening
        # cubic -w x^3/6 to leading order (k ~ sqrt(w) sin(a/2)); the polynomial terms add their
        # own k (`_cubic_modulus`; the sine alone, w = 1, keeps its radius of before)
        k = jnp.sqrt(self.w) * jnp.sin(0.5 * jnp.clip(jnp.abs(a), 1e-300, jnp.pi))
        k = jnp.maximum(k + jnp.where(self.w == 1, 0.0, _cubic_modulus(self, a)), 1e-300)
        return jnp.maximum(0.5 * jnp.pi, jnp.log(4 / k)) / jnp.sqrt(self.stiffness_bound(a))

    def frequency(self, a):
        # pi / (2 K(sin(a/2))) = AGM(1, cos(a/2)) for the sine, 1 for the linear share (their
        # squares mixed by the shares), times the polynomial terms' factor
        p, q = jnp.ones_like(a), jnp.maximum(jnp.cos(0.5 * jnp.minimum(jnp.abs(a), 3.1)), 1e-3)
        for _ in range(6):
            p, q = 0.5 * (p + q), jnp.sqrt(p * q)
        mixed = jnp.where(self.w == 1, p, jnp.sqrt(self.w * p * p + 1 - self.w))
        return mixed * _cubic_frequency(self, a)

    def stiffness_bound(self, a):
        return _cubic_bound(self, a)
