"""Free rope length profiles `l(t)` of the hoisting-rope model: piecewise polynomials of degree
<= 2 in `t`."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._checks import AbstractParams, _float, anything, nonnegative, positive

__all__ = ["LengthProfile", "ConstantSpeed", "Braking"]


class LengthProfile(AbstractParams):
    """Free rope length `l(t)` [m], piecewise polynomial of degree <= 2 in `t`."""

    @abc.abstractmethod
    def local(self, t: ArrayLike):
        """`(l, dl/dt, (d2l/dt2)/2)` of the polynomial piece that starts at or before `t`, so that
        `l(t + tau) = l + l' tau + (l''/2) tau^2` until `next_break(t)`."""

    def next_break(self, t: ArrayLike) -> Array:
        """First breakpoint of the profile strictly after `t` [s] (`inf` if none)."""
        return jnp.full_like(jnp.asarray(t, dtype=float), jnp.inf)

    @abc.abstractmethod
    def lifetime(self) -> Array:
        """Time at which the length reaches zero [s] (`inf` if it never does)."""

    def length(self, t: ArrayLike) -> Array:
        """Length `l(t)` [m]."""
        return self.local(t)[0]

    def rate(self, t: ArrayLike) -> Array:
        """`dl/dt` [m/s] (`-u` while hoisting at speed `u`)."""
        return self.local(t)[1]

    def accel(self, t: ArrayLike) -> Array:
        """`d2l/dt2` [m/s^2]."""
        return 2 * self.local(t)[2]

    def min_length(self, t1) -> Array:
        """Smallest length on `[0, t1]` [m] (the profiles are monotone)."""
        return jnp.minimum(self.length(0.0), self.length(t1))


class ConstantSpeed(LengthProfile):
    """Rope wound or unwound at constant speed: `l(t) = l0 - u t` (the paper's case).

    **Arguments:**

    - `l0`: initial free length [m], `> 0`.
    - `u`: hoisting speed [m/s]; `u > 0` hoists (the rope shortens and reaches zero length at
      `t = l0/u`), `u < 0` lowers, `u = 0` is a rope of fixed length.
    """

    l0: Array = eqx.field(converter=_float)
    u: Array = eqx.field(converter=_float, default=0.0)
    _limits: ClassVar[dict] = {"l0": (positive, "> 0 [m]"), "u": (anything, "a real number [m/s]")}

    def local(self, t):
        t = _float(t)
        return self.l0 - self.u * t, -self.u + jnp.zeros_like(t), jnp.zeros_like(t + self.u)

    def lifetime(self):
        up = self.u > 0
        return jnp.where(up, self.l0 / jnp.where(up, self.u, 1.0), jnp.inf)


class Braking(LengthProfile):
    """Constant speed `u` until `t_brake`, then uniform deceleration to rest at `t_stop`, then
    a fixed length (a drum that brakes; problem book, chapter 4.1.3, problems 11-12).

        l(t) = l0 - u t                                          for t < t_brake,
        l(t) = l0 - u t + u (t - t_brake)^2 / (2 (t_stop - t_brake))  for t_brake <= t < t_stop,
        l(t) = l0 - u (t_brake + t_stop) / 2                     for t >= t_stop.

    While braking, the frame decelerates and the load feels the inertial force `m l''`.

    **Arguments:**

    - `l0`: initial free length [m], `> 0`.
    - `u`: speed before braking [m/s] (`> 0` hoisting, `< 0` lowering).
    - `t_brake`: time the braking starts [s], `>= 0`.
    - `t_stop`: time the drum stops [s], `> t_brake`.
    """

    l0: Array = eqx.field(converter=_float)
    u: Array = eqx.field(converter=_float)
    t_brake: Array = eqx.field(converter=_float)
    t_stop: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {
        "l0": (positive, "> 0 [m]"),
        "u": (anything, "a real number [m/s]"),
        "t_brake": (nonnegative, ">= 0 [s]"),
        "t_stop": (positive, "> 0 [s]"),
    }

    # a relation, not a check at construction alone: `vmj.grid` and `eqx.tree_at` rebuild the
    # profile without `__init__`, and `validated` checks relations (a grid of t_brake past
    # t_stop was swept)
    _relations: ClassVar[dict] = {"t_stop": (lambda p: p.t_stop > p.t_brake, "> t_brake [s]")}

    def local(self, t):
        t = _float(t)
        tb, ts, u = self.t_brake, self.t_stop, self.u
        k = u / (2 * (ts - tb))  # l''/2 while braking
        braking = (t >= tb) & (t < ts)
        stopped = t >= ts
        l_run = self.l0 - u * t
        l_brake = l_run + k * (t - tb) ** 2
        l_end = self.l0 - u * (tb + ts) / 2
        l = jnp.where(stopped, l_end, jnp.where(braking, l_brake, l_run))
        rate = jnp.where(stopped, 0.0, jnp.where(braking, -u + 2 * k * (t - tb), -u))
        half_acc = jnp.where(braking, k, 0.0)
        return l, rate, half_acc

    def next_break(self, t):
        t = _float(t)
        return jnp.where(
            t < self.t_brake, self.t_brake, jnp.where(t < self.t_stop, self.t_stop, jnp.inf)
        )

    def lifetime(self):
        u, tb, ts, l0 = self.u, self.t_brake, self.t_stop, self.l0
        up = u > 0
        safe_u = jnp.where(up, u, 1.0)
        l_b = l0 - u * tb
        l_end = l0 - u * (tb + ts) / 2
        # while braking l(tb + s) = l_b - u s + u s^2 / (2 D): smaller root of l = 0
        D = ts - tb
        disc = jnp.maximum(1.0 - 2 * l_b / (safe_u * D), 0.0)
        s_zero = D * (1.0 - jnp.sqrt(disc))
        return jnp.where(
            up & (l_b <= 0), l0 / safe_u, jnp.where(up & (l_end <= 0), tb + s_zero, jnp.inf)
        )
