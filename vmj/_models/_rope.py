"""Mass on a hoisting rope of varying length (Osinski; `SYSTEMS.md` section 2).

    m x'' + (A e / l) x + (A b / l^2) x^2 + (A d / l^3) x^3 = -A T sign(x') + m l''(t)

`x` is the motion relative to the moving rope end, `l(t)` the free rope length given by a
length profile. The last term is the inertial force of the moving frame: zero at constant
speed (the paper's case), `m l''` while a drum brakes (the crane problems of the problem book).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, ArrayLike

from .._checks import (
    _float,
    _is_traced,
    anything,
    check,
    fail_if,
    nonnegative,
    positive,
    scalar,
    validated,
    warn_if_float32,
)
from .._closed_forms._osinski import action_law, energy_map_sequence, kbm
from .._exported import filter_jit
from .._laws._length import ConstantSpeed, LengthProfile
from .._numerics._series import cauchy, cauchy_term
from .._solution import RESULTS
from ._base import AbstractEnergyMap, check_horizon, require_scalar_fields

__all__ = ["Rope", "KGF", "kbm_amplitude", "kbm_frequency", "action_amplitude", "action_frequency"]

KGF = 9.80665
"""One kilogram-force (kG) [N]: the unit of the rope paper's technical units."""
RHO = 1.0  #: substep length in units of 1/omega_tangent(amplitude)
RHO_LENGTH = 0.25  #: substep length as a fraction of l/|dl/dt|
PIECES = 3  #: polynomial pieces of a length profile searched for a release (Braking has 3)


class Rope(AbstractEnergyMap):
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
    _limits: ClassVar[dict] = {
        "m": (positive, "> 0 [kg]"),
        "A": (positive, "> 0 [m^2]"),
        "e": (positive, "> 0 [Pa]"),
        "b": (anything, "a real number [Pa]"),
        "d": (nonnegative, ">= 0 [Pa]"),
        "T": (nonnegative, ">= 0 [Pa]"),
    }

    def __check_init__(self):
        if not isinstance(self.length, LengthProfile):
            raise ValueError(
                "length must be a length profile: vmj.ConstantSpeed(l0, u) or "
                "vmj.Braking(l0, u, t_brake, t_stop)"
            )

    @classmethod
    def from_technical(cls, m, A, e, b, d, T, length) -> Rope:
        """Build from technical units as printed in the paper: `m` [kG s^2/m], `A` [cm^2],
        `e`, `b`, `d`, `T` [kG/cm^2]; the profile stays in metres and seconds."""
        kg_cm2 = KGF * 1e4

        def si(x, factor):  # NumPy for numbers and lists; JAX arrays (traced ones too) as such
            return x * factor if isinstance(x, jax.Array) else np.multiply(x, factor)

        return cls(
            si(m, KGF),
            si(A, 1e-4),
            si(e, kg_cm2),
            si(b, kg_cm2),
            si(d, kg_cm2),
            si(T, kg_cm2),
            length,
        )

    @classmethod
    def paper(cls, u=0.0, T=0.0, cubic: bool = True, l0=10.0) -> Rope:
        """The paper's example (rope 6x37, 22 mm): `A = 1.74 cm^2`, `l0 = 10 m`,
        `m = 2 kG s^2/m`, `e = 0.8e6`, `d = 0.8e11` (or 0 with `cubic=False`), `b = 0`, with the
        friction `T` in kG/cm^2 (technical, as printed) and the speed `u` [m/s]."""
        return cls.from_technical(
            2.0, 1.74, 0.8e6, 0.0, 0.8e11 if cubic else 0.0, T, ConstantSpeed(l0, u)
        )

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

    exhausted: ClassVar[RESULTS] = RESULTS.length_exhausted
    lifetime_text: ClassVar[str] = "the time l(t) reaches 0 (the rope length reaches zero)"

    # -- the exact solver's half-swing ----------------------------------------------------------
    def rest(self, t, x):
        """At rest at `(t, x)` the mass sticks while the net force (spring plus frame inertia)
        is at most the static friction `A T`. It is pushed off again only where a new piece of
        the length profile starts with a larger force (a drum that begins to brake): a force
        that grows continuously inside a piece (a shortening rope stiffens) drags the mass
        along the edge of the stick zone with a velocity that only touches zero (quasi-static
        creep, no further turning points), which ends the decay (`stopped`)."""
        static = self.friction_force()
        stuck = jnp.abs(self.net_force(t, x)) <= static
        found = jnp.array(False)
        t_rel = p0 = t
        for _ in range(PIECES):
            brk = self.length.next_break(p0)
            p0 = jnp.where(jnp.isfinite(brk), brk, p0)
            here = (
                jnp.logical_not(found)
                & jnp.isfinite(brk)
                & (brk < self.lifetime())
                & (jnp.abs(self.net_force(p0, x)) > static)
            )
            t_rel = jnp.where(here, p0, t_rel)
            found = found | here
        t_go = jnp.where(stuck, t_rel, t)
        s = jnp.where(self.net_force(t_go, x) >= 0, 1.0, -1.0)
        return s, t_go, stuck & jnp.logical_not(found)

    def swing_scale(self, t, x):
        """`|x|` plus the static deflection of the frame's inertial force."""
        return jnp.abs(x) + jnp.abs(self.m * self.length.accel(t)) / (
            self.A * self.e
        ) * self.length.length(t)

    def taylor(self, t, x, v, s, order: int):
        """On each polynomial piece of the length profile `g_k(tau) = 1/l(t + tau)^k` has a
        Taylor series given by a recurrence (`l` is a polynomial of degree <= 2); the
        coefficients of `x` then follow from

            m (n+2)(n+1) x_{n+2} = -A [e (g_1 x)_n + b (g_2 x^2)_n + d (g_3 x^3)_n]
                                   + [n = 0] (2 m l_2 - A T s)

        with Cauchy products `( )_n`: O(order^2) multiply-adds."""
        l, l1, l2 = self.length.local(t)
        k = order + 1

        def reciprocal(n, g):  # g = 1/l(t + tau): l0 g_n + l1 g_{n-1} + l2 g_{n-2} = 0
            return g.at[n].set(-(l1 * g[n - 1] + l2 * jnp.where(n >= 2, g[n - 2], 0.0)) / l)

        g1 = lax.fori_loop(1, k, reciprocal, jnp.zeros(k, dtype=l.dtype).at[0].set(1.0 / l))
        g2 = cauchy(g1, g1)
        g3 = cauchy(g2, g1)
        A, m = self.A, self.m
        force0 = 2 * m * l2 - A * self.T * s

        def body(n, carry):
            xs, x2, x3 = carry
            x2 = x2.at[n].set(cauchy_term(xs, xs, n))
            x3 = x3.at[n].set(cauchy_term(x2, xs, n))
            rhs = -A * (
                self.e * cauchy_term(g1, xs, n)
                + self.b * cauchy_term(g2, x2, n)
                + self.d * cauchy_term(g3, x3, n)
            )
            rhs = rhs + jnp.where(n == 0, force0, 0.0)
            return xs.at[n + 2].set(rhs / (m * (n + 1) * (n + 2))), x2, x3

        zeros = jnp.zeros(k, dtype=jnp.result_type(x, v, l))
        xs0 = zeros.at[0].set(x).at[1].set(v)
        xs, _, _ = lax.fori_loop(0, order - 1, body, (xs0, zeros, zeros))
        return [xs[j] for j in range(k)]

    def substep(self, t, scale):
        """At most `RHO / omega_tangent(scale)` (the cubic spring shortens the radius of
        convergence), `RHO_LENGTH l/|l'|` (the singularity at `l = 0`) and the distance to the
        next breakpoint of the profile."""
        l, rate, _ = self.length.local(t)
        h_omega = RHO / self.omega(t, scale)
        moving = rate != 0
        h_len = jnp.where(moving, RHO_LENGTH * l / jnp.where(moving, jnp.abs(rate), 1.0), jnp.inf)
        brk = self.length.next_break(t)
        h = jnp.minimum(jnp.minimum(h_omega, h_len), brk - t)
        # limited by the approach of the zero-length time only while the rope shortens: a
        # lowered rope that runs out of steps (a very slow swing) has not run out of length
        # (it is reported as the step limit)
        return h, (h_len < h_omega) & (rate < 0), jnp.where(h >= brk - t, brk, t + h)

    def half_period(self, t, scale):
        """`pi / omega_tangent(scale)` at time `t` [s]."""
        return jnp.pi / self.omega(t, scale)

    def horizon(self, a0, n: int):
        """1.3 times the sum of linear half-periods (the longest for a hardening rope), kept
        short of the zero-length time."""
        return super().horizon(jnp.zeros_like(jnp.asarray(a0, dtype=float)), n)

    # -- the exact energy map of a rope of fixed length -----------------------------------------
    def energy_map(self, a0, n: int):
        """Exact turning points of a rope of fixed length (`u = 0`) from the energy balance over
        each half-swing (see [`vmj.EnergyBalance`][])."""
        return energy_map_sequence(self, a0, n)

    def guard_energy_map(self):
        if not isinstance(self.length, ConstantSpeed):
            raise ValueError(
                "the energy map needs a vmj.ConstantSpeed length profile "
                f"(got {type(self.length).__name__})"
            )
        u = self.length.u
        if not _is_traced(u):
            if float(u) != 0:
                raise ValueError(
                    f"u must be 0 for the energy map (a rope of fixed length; got {float(u)})"
                )
            return self
        return eqx.tree_at(
            lambda r: r.length.u,
            self,
            fail_if(u, u != 0, "u must be 0 for the energy map (a rope of fixed length)"),
        )


# -- the averaged laws (closed forms in _closed_forms/_osinski.py) -------------------------------
def _averaged_inputs(rope, a0, t):
    warn_if_float32()
    if not isinstance(rope, Rope):
        raise ValueError(f"rope must be a vmj.Rope (got {type(rope).__name__})")
    if not isinstance(rope.length, ConstantSpeed):
        raise ValueError(
            "the averaged laws need a vmj.ConstantSpeed length profile "
            f"(got {type(rope.length).__name__})"
        )
    require_scalar_fields(rope)
    rope = validated(rope)
    a0 = _float(scalar("a0", check("a0", a0, positive, "> 0 [m]")))
    t = check("t", t, lambda x: x >= 0, ">= 0 [s]")
    check_horizon(rope, t, "t")
    return rope, a0, _float(t)


@filter_jit
def _kbm(rope, a0, t):
    return kbm(rope, a0, t)


@filter_jit
def _action(rope, a0, ts):
    return action_law(rope, a0, ts)


def _action_entry(rope, a0, t):
    rope, a0, t = _averaged_inputs(rope, a0, t)
    amp, freq = _action(rope, a0, jnp.atleast_1d(t))
    return amp.reshape(jnp.shape(t)), freq.reshape(jnp.shape(t))


def kbm_amplitude(rope: Rope, a0: ArrayLike, t: ArrayLike) -> Array:
    """First-order (Krylov-Bogolyubov) amplitude of the paper, corrected (`SYSTEMS.md` s. 2):

        a(t) = a0 (l/l0)^(1/4) - (4 D / (5 u)) (l0^(5/4) l^(1/4) - l^(3/2)),
        a(t) = a0 - D sqrt(l0) t  for u = 0,   D = 2 T / (pi sqrt(e m / A)),

    the solution of `da/dt = -a u/(4 l) - D sqrt(l)` (the paper's (2.6)); clipped at 0 once
    friction has stopped the motion. The cubic and quadratic terms do not enter at first order.

    **Arguments:** `rope` ([`vmj.Rope`][] with a [`vmj.ConstantSpeed`][] profile), `a0` [m] `> 0`,
    `t` [s] (array), `0 <= t` below the zero-length time `l0/u`.
    **Returns:** the amplitude [m] at each `t`. Differentiable in every parameter.
    """
    return _kbm(*_averaged_inputs(rope, a0, t))[0]


def kbm_frequency(rope: Rope, a0: ArrayLike, t: ArrayLike) -> Array:
    """First-order frequency (the paper's (2.9)) [rad/s]:
    `Omega = omega + 3 A d a^2 / (8 m omega l^3)`, `omega = sqrt(A e/(m l))`, with `a` from
    [`vmj.kbm_amplitude`][]. Arguments as for [`vmj.kbm_amplitude`][]."""
    return _kbm(*_averaged_inputs(rope, a0, t))[1]


def action_amplitude(rope: Rope, a0: ArrayLike, t: ArrayLike) -> Array:
    """Averaged amplitude from the action of the nonlinear rope, valid when the cubic term is
    not small (beyond the paper's first order).

    The action `I(E, l) = (1/pi) int sqrt(2 m (E - V(x, l))) dx` over a swing is an adiabatic
    invariant of the slowly changing length, so only friction changes it:
    `dI/dt = -(A T/pi)(x_+ - x_-)`, with the turning points `x_+-` of the swing of action `I` at
    the current length. Integrated with diffrax in `J = sqrt(I)`. Returns the half peak-to-peak
    amplitude `(x_+ - x_-)/2` [m] (the amplitude for `b = 0`), 0 once friction has stopped the
    motion. With `d = b = 0` it reduces to [`vmj.kbm_amplitude`][].

    **Arguments:** `rope` ([`vmj.Rope`][] with a [`vmj.ConstantSpeed`][] profile), `a0` [m] `> 0`
    (release from rest at `x = -a0`), `t` [s] (array, `>= 0`, below the zero-length time).
    """
    return _action_entry(rope, a0, t)[0]


def action_frequency(rope: Rope, a0: ArrayLike, t: ArrayLike) -> Array:
    """Angular frequency `2 pi / period` [rad/s] of the swing of the action-averaged law (the
    amplitude-dependent frequency of the nonlinear rope), at times `t` [s]. Arguments as for
    [`vmj.action_amplitude`][]."""
    return _action_entry(rope, a0, t)[1]
