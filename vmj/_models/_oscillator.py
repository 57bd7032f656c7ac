"""The identification oscillator: one degree of freedom (per unit mass or inertia) with a
restoring law and dissipation laws chosen independently,

    x'' + sum_d D_d(x, x') + omega^2 r(x) = 0,    x(0) = -a0,  x'(0) = 0.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array

from .._checks import _float, positive
from .._closed_forms._oscillator import energy_map_sequence
from .._laws._dissipation import CoulombDamping, DissipationLaw, QuadraticDamping, ViscousDamping
from .._laws._restoring import LinearRestoring, RestoringLaw, SineRestoring
from ._base import AbstractEnergyMap

__all__ = ["Oscillator"]

ENTIRE = 3.5  #: substep in units of 1/omega where the series is entire (as the variable mass:
#: one substep for a half-swing of pi/omega)
RHO = 0.3  #: substep as a fraction of the bound on the series' radius of convergence
FAST_MARGIN = 0.5  #: margin [1/omega] of the estimated fast passage of a pendulum, undamped
AGM_STEPS = 12  #: arithmetic-geometric mean steps for K(k): enough down to k' = 1e-300


def _laws(dissipation) -> tuple:
    if isinstance(dissipation, DissipationLaw):
        return (dissipation,)
    return tuple(dissipation)


class Oscillator(AbstractEnergyMap):
    """One-degree-of-freedom oscillator per unit mass (or inertia) whose restoring law and
    dissipation laws are chosen independently:

        x'' + sum_d D_d(x, x') + omega^2 r(x) = 0,

    released from rest at `x(0) = -a0`. At a turning point the mass sticks for good while
    `|r(x)|` is at most the static level `xS` of its [`vmj.CoulombDamping`][] law.

    **Arguments:**

    - `omega`: small-amplitude natural frequency [rad/s], `> 0`.
    - `restoring`: the restoring law `r(x)`, `r'(0) = 1`: [`vmj.LinearRestoring`][] (default),
      [`vmj.PolynomialRestoring`][]`(b2, b3)` or [`vmj.SineRestoring`][]`(b2, b3)` (the
      pendulum, `x` in rad).
    - `dissipation`: a tuple of dissipation laws, summed: [`vmj.ViscousDamping`][]`(zeta)`,
      [`vmj.CoulombDamping`][]`(xF, xS)`, [`vmj.QuadraticDamping`][]`(cq)`; default none.

    Positions (`a0`, `xF`, `xS`, the turning points) are in one unit of your choice (rad for
    the pendulum; a fit in degrees converts its angles, and `xF`, `xS`, `1/cq`, `1/b2`,
    `sqrt(1/b3)` with them). Every solver applies: [`vmj.Exact`][] (Taylor series of each
    half-swing), [`vmj.Smoothed`][] and [`vmj.EnergyBalance`][] (exact for dry friction, and for
    the linear law with viscous damping; averaged with speed-dependent damping otherwise, see
    `EnergyBalance`).

    Example:

        osc = vmj.Oscillator.pendulum(omega=6.3, zeta=0.002, xF=1e-3, cq=0.01)
        seq = vmj.turning_points(osc, jnp.deg2rad(60.0), 40)  # exact
    """

    omega: Array = eqx.field(converter=_float)
    restoring: RestoringLaw = eqx.field(default_factory=LinearRestoring)
    dissipation: tuple = eqx.field(default=(), converter=_laws)
    _limits: ClassVar[dict] = {"omega": (positive, "> 0 [rad/s]")}
    #: substeps per half-swing of a pendulum (measured): 4 to 11 released at up to 2.8 rad,
    #: 12 to 15 at 3.1, 15 to 21 at 3.14 (zeta <= 0.2, cq <= 0.1), 17 to 23 at pi - 1e-4
    #: (179.994 deg; zeta, cq <= 0.05); a larger limit costs little where the swings need
    #: fewer
    exact_substeps: ClassVar[int] = 24

    def __check_init__(self):
        if not isinstance(self.restoring, RestoringLaw):
            raise ValueError(
                "restoring must be a restoring law: vmj.LinearRestoring(), "
                "vmj.PolynomialRestoring(b2, b3) or vmj.SineRestoring(b2, b3)"
            )
        if not all(isinstance(d, DissipationLaw) for d in self.dissipation):
            raise ValueError(
                "dissipation must be a tuple of dissipation laws: "
                "vmj.ViscousDamping(zeta), vmj.CoulombDamping(xF, xS), "
                "vmj.QuadraticDamping(cq)"
            )

    @classmethod
    def pendulum(cls, omega, zeta=0.0, xF=0.0, xS=None, cq=0.0, b2=0.0, b3=0.0) -> Oscillator:
        """A pendulum, angles in rad: `r = sin(x) + b2 x^2 + b3 x^3` with viscous damping
        `zeta` [-], dry friction `xF` (kinetic) and `xS` (static, default `xF`) [rad] and
        quadratic drag `cq` [1/rad]. Every law is present whatever its value, so that every
        subset of parameters shares one compiled model."""
        return cls(
            omega,
            SineRestoring(b2, b3),
            (ViscousDamping(zeta), CoulombDamping(xF, xS), QuadraticDamping(cq)),
        )

    @classmethod
    def linear(cls, omega, zeta=0.0, xF=0.0, xS=None) -> Oscillator:
        """The linear oscillator with viscous damping `zeta` [-] and dry friction `xF`, `xS`
        [position unit]: `x'' + 2 zeta omega x' + omega^2 (x + xF sign(x')) = 0`, whose energy
        balance is the exact closed-form half-swing map."""
        return cls(omega, LinearRestoring(), (ViscousDamping(zeta), CoulombDamping(xF, xS)))

    @property
    def position_unit(self) -> str:
        return "rad" if self.restoring.angular else "position unit"

    def release_range(self):
        """A pendulum is released below the upright position: `0 < a0 < pi` [rad]."""
        if self.restoring.angular:
            return (
                lambda a: (a > 0) & (a < np.pi),
                "in (0, pi) [rad] (angles are in radians: convert degrees with np.deg2rad)",
            )
        return super().release_range()

    # -- the equation of motion, written once ---------------------------------------------------
    def levels(self):
        """Total dry-friction levels `(kinetic, static)` [position unit]."""
        kinetic = static = jnp.zeros_like(self.omega)
        for d in self.dissipation:
            k, s = d.levels()
            kinetic, static = kinetic + k, static + s
        return kinetic, static

    def acceleration(self, t, x, v, sgn):
        """`x''` at position `x`, velocity `v`, with `sgn` standing for `sign(v)` (exactly +-1
        in the exact solver)."""
        om = self.omega
        return -sum(
            (d.force(om, x, v, sgn) for d in self.dissipation), om * om * self.restoring.value(x)
        )

    def vector_field(self, t, y, w):
        """The smoothed ODE: each law's smoothed force (`sign(v)` as `tanh(v/w)`; the static
        friction level as the limit of the dry friction at small speed)."""
        x, v = y[0], y[1]
        om = self.omega
        acc = -sum(
            (d.smoothed_force(om, x, v, w) for d in self.dissipation),
            om * om * self.restoring.value(x),
        )
        return jnp.stack([v, acc])

    def velocity_scale(self, a0) -> Array:
        """`omega a0` [position unit/s]."""
        return a0 * self.omega

    # -- the exact solver's half-swing ----------------------------------------------------------
    def rest(self, t, x):
        """At rest at `x` the mass sticks for good while `|r(x)| <= xS`; otherwise it moves
        against the restoring force at once."""
        _, static = self.levels()
        r = self.restoring.value(x)
        return jnp.where(r > 0, -1.0, 1.0), t, jnp.abs(r) <= static

    def swing_scale(self, t, x):
        """`(amplitude, t_fast, margin)` of the half-swing leaving rest at `(t, x)`: `|x|`, and
        for the pendulum the estimated time of its fast passage through the bottom of the well
        and that estimate's margin [s] (`_fast_passage`; see `substep`)."""
        t, x = lax.stop_gradient((t, x))
        amplitude = jnp.abs(x)
        return (amplitude, *self._fast_passage(t, amplitude))

    def _fast_passage(self, t, amplitude):
        """`(t_fast, margin)` [s]: when a pendulum (the sine law alone) released from rest at
        amplitude `amplitude` at time `t` passes the bottom of its well, `t + K(k)/omega`, and
        a margin for the error of that estimate; `(t, inf)` for every other law (no
        estimate).

        The elliptic modulus is taken from the potential that the dry friction `xF` tilts,
        `U(x) = 1 - cos x + xF x` (the direction of motion positive): `k'^2` is the energy
        still missing to the hilltop behind the start, over the height of that hilltop above
        the bottom (`cos(a/2)^2` without friction), written without cancellation near the
        hilltop, where `K = ln(4/k') + ...` is what matters. Measured against a DOP853
        integration (a0 from 0.5 to 3.14 rad, xF up to 0.4, zeta up to 0.5, cq up to 1): the
        speed peaks within `0.35 + 0.95 zeta K` of the estimate (damping slows the escape
        from the hilltop); the margin is `0.5 + 2 zeta K` (in units of `1/omega`). A wrong
        estimate meets the exact solver's guard on each series' tail: a reported failure, or
        at worst an error of the guard's size (1e-9 relative)."""
        law = self.restoring
        inf = jnp.full_like(amplitude, jnp.inf)
        if not isinstance(law, SineRestoring):
            return t + 0 * amplitude, inf
        kinetic = self.levels()[0]
        xf = jnp.clip(kinetic, 0.0, 0.5)  # (measured up to 0.4; no estimate above 0.5)
        y0 = jnp.pi - jnp.minimum(amplitude, jnp.pi)  # distance of the start from upright
        yh = jnp.arcsin(xf)  # ... of the hilltop behind it
        gap = 2 * jnp.sin(0.5 * (y0 + yh)) * jnp.sin(0.5 * (y0 - yh)) - xf * (y0 - yh)
        height = 2 * jnp.sqrt(1 - xf * xf) - xf * (jnp.pi - 2 * yh)
        kp = jnp.sqrt(jnp.clip(gap / height, 1e-300, 1.0))
        p, q = jnp.ones_like(kp), kp
        for _ in range(AGM_STEPS):
            p, q = 0.5 * (p + q), jnp.sqrt(p * q)
        quarter = 0.5 * jnp.pi / p  # K(k)
        zeta = sum((d.zeta for d in self.dissipation if isinstance(d, ViscousDamping)), 0.0)
        margin = (FAST_MARGIN + 2 * zeta * quarter) / self.omega
        pure = (law.w == 1) & (law.b2 == 0) & (law.b3 == 0) & (kinetic <= 0.5)
        return t + quarter / self.omega, jnp.where(pure, margin, inf)

    def taylor(self, t, x, v, s, order: int):
        """Within a half-swing (velocity sign `s`) the coefficients of `x` follow from

            (n + 2)(n + 1) x_{n+2} = -sum_d (D_d)_n - omega^2 (r)_n,

        each law giving the coefficient `n` of its term from those of `x` and `v` so far
        (Cauchy products; the sine by its recurrence): O(order^2) multiply-adds."""
        k = order + 1
        om = self.omega
        dtype = jnp.result_type(x, v, om)
        xs = jnp.zeros(k, dtype=dtype).at[0].set(x).at[1].set(v)
        scale = jnp.arange(1, k + 1, dtype=dtype)

        def body(n, carry):
            xs, work = carry
            vs = scale * jnp.concatenate([xs[1:], jnp.zeros(1, dtype=dtype)])
            r_n, work = self.restoring.series_term(n, xs, work)
            rhs = sum((d.series_term(om, n, xs, vs, s) for d in self.dissipation), om * om * r_n)
            return xs.at[n + 2].set(-rhs / ((n + 1) * (n + 2))), work

        xs, _ = lax.fori_loop(0, order - 1, body, (xs, self.restoring.series_start(x, k)))
        return [xs[j] for j in range(k)]

    def substep(self, t, scale):
        """`min(3.5/omega, 0.3 R)`, `R` the smallest bound on the series' radius of convergence
        that the laws give for a swing of amplitude `scale[0]` (the sine's `K'(k)/omega`, the
        polynomial's shrinking with amplitude, quadratic drag's `1/(cq v_max)`). The results do
        not depend on where the substeps end: no gradient flows through it.

        The pendulum's singularities (the poles of `sn`) lie `K'(k)/omega` off the real axis
        at the fast passages through the bottom of the well, so at a time `Delta` away from
        the passage the series converges within `sqrt(Delta^2 + (K'/omega)^2)`: `Delta` is
        counted from the estimated passage (`swing_scale`) less its margin. Near the
        separatrix the swing spends most of its `2 K(k)/omega` creeping near the hilltops,
        far from the passage: `K'` alone made the substeps `0.47/omega` and the count grow
        like `4.3 K` (17 to 23 at a0 = 3.1 rad, 26 to 37 at 3.14), the local radius makes it
        about `K + 10` (12 to 15, 15 to 21)."""
        amplitude, t_fast, margin = scale
        om = self.omega
        law = self.restoring
        vmax = om * jnp.sqrt(2 * jnp.maximum(law.potential(amplitude), law.potential(-amplitude)))
        away = jnp.maximum(jnp.abs(t - t_fast) - margin, 0.0)
        radius = jnp.hypot(away, law.radius(amplitude) / om)
        for d in self.dissipation:
            radius = jnp.minimum(radius, d.radius(om, vmax))
        h = lax.stop_gradient(jnp.minimum(ENTIRE / om, RHO * radius))
        return h, jnp.zeros_like(h, dtype=bool), t + h

    def half_period(self, t, scale):
        """`pi / (omega Omega(scale))` [s], `Omega` the restoring law's frequency estimate."""
        return jnp.pi / (self.omega * self.restoring.frequency(scale[0]))

    def horizon(self, a0, n: int):
        """1.3 times `n + 1` of the longer of the half-periods at `a0` and at small
        amplitude."""
        slow = jnp.minimum(self.restoring.frequency(a0), 1.0)
        return 1.3 * (n + 1) * jnp.pi / (self.omega * slow)

    # -- the energy balance -----------------------------------------------------------------------
    def energy_map(self, a0, n: int):
        """Turning points from the half-swing energy balance (see [`vmj.EnergyBalance`][]):
        exact with dry friction alone and for the linear law with viscous damping, averaged
        otherwise."""
        return energy_map_sequence(self, a0, n)
