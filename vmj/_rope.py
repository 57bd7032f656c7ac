"""Mass on a hoisting rope of varying length (Osinski; `SYSTEMS.md` section 2).

    m x'' + (A e / l) x + (A b / l^2) x^2 + (A d / l^3) x^3 = -A T sign(x') + m l''(t)

`x` is the motion relative to the moving rope end, `l(t)` the free rope length given by a
length profile. The last term is the inertial force of the moving frame: zero at constant
speed (the paper's case), `m l''` while a drum brakes (the crane problems of the problem book).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._checks import _is_traced, anything, check, nonnegative, positive
from ._models import _Checked, _float, validated

__all__ = ["LengthProfile", "ConstantSpeed", "Braking", "Rope", "KGF"]

KGF = 9.80665  #: one kilogram-force (kG) [N]




class LengthProfile(_Checked):
    """Free rope length `l(t)` [m], piecewise polynomial of degree <= 2 in `t`."""

    def local(self, t: ArrayLike):
        """`(l, dl/dt, (d2l/dt2)/2)` of the polynomial piece that starts at or before `t`, so that
        `l(t + tau) = l + l' tau + (l''/2) tau^2` until `next_break(t)`."""
        raise NotImplementedError

    def next_break(self, t: ArrayLike) -> Array:
        """First breakpoint of the profile strictly after `t` [s] (`inf` if none)."""
        return jnp.full_like(jnp.asarray(t, dtype=float), jnp.inf)

    def lifetime(self) -> Array:
        """Time at which the length reaches zero [s] (`inf` if it never does)."""
        raise NotImplementedError

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
    _limits = {"l0": (positive, "> 0 [m]"), "u": (anything, "a real number [m/s]")}

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
    _limits = {
        "l0": (positive, "> 0 [m]"),
        "u": (anything, "a real number [m/s]"),
        "t_brake": (nonnegative, ">= 0 [s]"),
        "t_stop": (positive, "> 0 [s]"),
    }

    def __check_init__(self):
        validated(self)
        gap = self.t_stop - self.t_brake
        if not _is_traced(gap):
            check("t_stop", np.asarray(gap), positive, "> t_brake [s] (t_stop - t_brake)")

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
        return jnp.where(t < self.t_brake, self.t_brake,
                         jnp.where(t < self.t_stop, self.t_stop, jnp.inf))

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


class Rope(_Checked):
    """Mass on a hoisting rope of varying length with friction between the wires (Osinski):

        m x'' + (A e/l) x + (A b/l^2) x^2 + (A d/l^3) x^3 = -A T sign(x') + m l''(t),

    with the rope law `sigma - sigma0 = e s + b s^2 + d s^3 + T sign(s')`, `s = x/l`, released
    from rest at `x(0) = -a0`. The mass sticks at a turning point when the net force on it
    (spring plus frame inertia) is at most the static friction `A T`.

    **Arguments:**

    - `m`: suspended mass [kg], `> 0`.
    - `A`: rope cross-section [m^2], `> 0`.
    - `e`: linear modulus of the rope [Pa], `> 0`.
    - `b`: quadratic coefficient [Pa], any sign.
    - `d`: cubic coefficient [Pa], `>= 0`.
    - `T`: friction stress between the wires [Pa], `>= 0`.
    - `length`: the length profile `l(t)`, a [`vmj.ConstantSpeed`][] or [`vmj.Braking`][].

    Technical units (kG = 9.80665 N, as printed in the paper) convert with
    [`vmj.Rope.from_technical`][].
    """

    m: Array = eqx.field(converter=_float)
    A: Array = eqx.field(converter=_float)
    e: Array = eqx.field(converter=_float)
    b: Array = eqx.field(converter=_float)
    d: Array = eqx.field(converter=_float)
    T: Array = eqx.field(converter=_float)
    length: LengthProfile
    _limits = {
        "m": (positive, "> 0 [kg]"),
        "A": (positive, "> 0 [m^2]"),
        "e": (positive, "> 0 [Pa]"),
        "b": (anything, "a real number [Pa]"),
        "d": (nonnegative, ">= 0 [Pa]"),
        "T": (nonnegative, ">= 0 [Pa]"),
    }

    def __check_init__(self):
        if not isinstance(self.length, LengthProfile):
            raise ValueError("length must be a length profile: vmj.ConstantSpeed(l0, u) or "
                             "vmj.Braking(l0, u, t_brake, t_stop)")
        validated(self)

    @classmethod
    def from_technical(cls, m, A, e, b, d, T, length) -> "Rope":
        """Build from technical units as printed in the paper: `m` [kG s^2/m], `A` [cm^2],
        `e`, `b`, `d`, `T` [kG/cm^2]; the profile stays in metres and seconds."""
        kg_cm2 = KGF * 1e4
        return cls(np.multiply(m, KGF), np.multiply(A, 1e-4), np.multiply(e, kg_cm2),
                   np.multiply(b, kg_cm2), np.multiply(d, kg_cm2), np.multiply(T, kg_cm2), length)

    @classmethod
    def paper(cls, u=0.0, T=0.0, cubic: bool = True, l0=10.0) -> "Rope":
        """The paper's example (rope 6x37, 22 mm): `A = 1.74 cm^2`, `l0 = 10 m`,
        `m = 2 kG s^2/m`, `e = 0.8e6`, `d = 0.8e11` (or 0 with `cubic=False`), `b = 0`, with the
        friction `T` in kG/cm^2 (technical, as printed) and the speed `u` [m/s]."""
        return cls.from_technical(2.0, 1.74, 0.8e6, 0.0, 0.8e11 if cubic else 0.0, T,
                                  ConstantSpeed(l0, u))

    # -- the equation of motion, written once ---------------------------------------------------
    def spring(self, t, x) -> Array:
        """Elastic rope force on the mass, as it enters the left-hand side [N]."""
        l = self.length.length(t)
        s = x / l
        return self.A * s * (self.e + s * (self.b + s * self.d))

    def potential(self, x, l) -> Array:
        """Elastic energy `A e x^2/(2l) + A b x^3/(3l^2) + A d x^4/(4l^3)` [J] at length `l` [m]."""
        s = x / l
        return self.A * l * s * s * (self.e / 2 + s * (self.b / 3 + s * self.d / 4))

    def net_force(self, t, x) -> Array:
        """Force on the mass other than friction: `-spring + m l''` [N]."""
        return -self.spring(t, x) + self.m * self.length.accel(t)

    def acceleration(self, t, x, v, sgn):
        """`x''` [m/s^2] at time `t` [s], position `x` [m], velocity `v` [m/s], with `sgn` standing
        for `sign(x')` (exactly +-1 in the exact solver, a smooth function in the smoothed one)."""
        return (self.net_force(t, x) - self.A * self.T * sgn) / self.m

    def friction_force(self) -> Array:
        """Sliding and static friction force `A T` [N]."""
        return self.A * self.T

    def omega(self, t, a=0.0) -> Array:
        """Angular frequency [rad/s] of the tangent stiffness at deflection `a` [m] at time `t`;
        `a = 0` gives the linear `sqrt(A e/(m l))`."""
        l = self.length.length(t)
        s = jnp.abs(a) / l
        k = self.A * (self.e + 2 * jnp.abs(self.b) * s + 3 * self.d * s * s) / l
        return jnp.sqrt(k / self.m)

    def lifetime(self) -> Array:
        """Time at which the rope length reaches zero [s] (`inf` if it never does)."""
        return self.length.lifetime()

    def velocity_scale(self, a0) -> Array:
        """Velocity scale `a0 sqrt(A e/(m l0))` [m/s] of a (linear) swing of amplitude `a0` [m]."""
        return a0 * self.omega(0.0)

    _lifetime_text = "the time l(t) reaches 0"


def check_horizon(model: Rope, t1, name: str = "t1") -> None:
    """Refuse (ValueError) a concrete horizon `t1` at or beyond the zero-length time."""
    life = model.lifetime()
    if _is_traced(life) or _is_traced(t1):
        return
    t_max = float(np.max(np.asarray(t1)))
    if t_max >= float(life):
        raise ValueError(
            f"{name} must be below the time the rope length reaches zero, "
            f"t = {float(life):.6g} s (got {t_max:.6g}); the model is meaningless for l <= 0"
        )
