"""What every model provides to the solvers.

Models are the *what*, solvers the *how* (as diffrax separates terms from solvers):

- [`AbstractModel`][vmj.AbstractModel]: anything [`vmj.simulate`][] integrates: an equation of
  motion `x'' = acceleration(t, x, v, sgn)` with `sgn` standing for the sign of the sliding
  velocity, its state for the ODE solver, a velocity scale and a lifetime.
- [`AbstractDecayModel`][vmj.AbstractDecayModel]: a one-degree-of-freedom oscillator with dry
  friction released from rest, which [`vmj.turning_points`][] solves half-swing by half-swing: the
  stick rule at a turning point, and for the exact solver the Taylor series of a half-swing
  (fixed friction sign) and its substep.
- Capabilities that exist for some models only, each an abstract base of its own:
  [`AbstractEnergyMap`][vmj.AbstractEnergyMap] (a closed-form half-swing map, for
  [`vmj.EnergyBalance`][]), [`AbstractAnalytic`][vmj.AbstractAnalytic] (a closed-form response,
  for [`vmj.ClosedForm`][]), [`AbstractLimitCycle`][vmj.AbstractLimitCycle] (a self-excited
  cycle, for [`vmj.limit_cycle`][]).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array

from .._checks import AbstractParams, _is_traced, instance_of, own_fields, positive
from .._solution import RESULTS

__all__ = [
    "check_horizon",
    "require_scalar_fields",
    "AbstractModel",
    "AbstractDecayModel",
    "AbstractEnergyMap",
    "AbstractAnalytic",
    "AbstractLimitCycle",
]


class AbstractModel(AbstractParams):
    """Base of every model: an equation of motion that [`vmj.simulate`][] integrates.

    Concrete models set the class constants below where their defaults do not fit.
    """

    #: relative tolerance of the smoothed ODE solve ([`vmj.Smoothed`][]'s default)
    smoothed_rtol: ClassVar[float] = 1e-10
    #: step limit of the smoothed ODE solve
    smoothed_max_steps: ClassVar[int] = 200_000
    #: whether the smoothed ODE is stiff (an implicit solver, Kvaerno5, instead of Dopri8)
    smoothed_stiff: ClassVar[bool] = False
    #: the status reported when a solve runs into the model's lifetime
    exhausted: ClassVar[RESULTS] = RESULTS.mass_exhausted
    #: what the lifetime is, for error messages
    lifetime_text: ClassVar[str] = "the model's lifetime"
    #: the unit of positions (for error messages)
    position_unit: ClassVar[str] = "m"

    @abc.abstractmethod
    def acceleration(self, t, x, v, sgn) -> Array:
        """`x''` at time `t` [s], position `x`, velocity `v`, with `sgn` standing for the sign of
        the sliding velocity (exactly +-1 in the exact solvers, a smooth function in the
        smoothed one; ignored by models without dry friction)."""

    @abc.abstractmethod
    def velocity_scale(self, a0) -> Array:
        """Velocity scale of a swing of amplitude `a0` (the unit of the smoothing velocity)."""

    def lifetime(self) -> Array:
        """Time at which the model stops being meaningful [s] (`inf` if never)."""
        return jnp.asarray(jnp.inf)

    def smoothing_scale(self, x0, v0) -> Array:
        """The velocity scale of a motion from `(x0, v0)`; the default smoothing velocity of
        [`vmj.Smoothed`][] is `1e-4` of it."""
        return self.velocity_scale(jnp.abs(x0)) + jnp.abs(v0)

    def length_scale(self, x0, v0) -> Array:
        """The length scale of a motion from `(x0, v0)` (the ODE's absolute tolerance is the
        relative one times it)."""
        return jnp.abs(x0) + jnp.abs(v0) / self.velocity_scale(1.0)

    def state_scale(self, x0, v0) -> Array:
        """The scale of each component of the ODE state (`initial_state`) of a motion from
        `(x0, v0)`, in its own unit: the length scale for the position, that times
        `velocity_scale(1.0)` for the velocity. The smoothed solver's absolute tolerance is
        its relative tolerance times this."""
        length = self.length_scale(x0, v0)
        return jnp.stack([length, length * self.velocity_scale(1.0)])

    # -- the smoothed ODE: sign(v) replaced by tanh(v/w) -------------------------------------
    def initial_state(self, x0, v0) -> Array:
        """The ODE state at `t = 0` from position and velocity."""
        return jnp.stack([x0, v0])

    def vector_field(self, t, y, w) -> Array:
        """Right-hand side of the smoothed ODE with smoothing velocity `w`."""
        x, v = y[0], y[1]
        return jnp.stack([v, self.acceleration(t, x, v, jnp.tanh(v / w))])

    def observe(self, y):
        """`(x, v)` from an ODE state."""
        return y[..., 0], y[..., 1]


class AbstractDecayModel(AbstractModel):
    """A one-degree-of-freedom oscillator with dry friction released from rest at `x = -a0`,
    solved half-swing by half-swing.

    Within a half-swing the friction sign `s` is fixed; the exact solver
    ([`vmj.Exact`][]) advances by Taylor polynomials of the half-swing solution (`taylor`) over
    substeps (`substep`) to the velocity zero, where the stick rule (`rest`) decides whether the
    mass moves on.
    """

    #: the exact solver's default step limit per half-swing (`vmj.Exact().max_substeps`)
    exact_substeps: ClassVar[int] = 8
    #: whether `taylor` is straight-line code (no loop), cheap enough for the exact solver's
    #: Newton iterations to recompute in a single solve (`vmj.Exact(one_lane=True)`)
    straight_line_taylor: ClassVar[bool] = False

    def release_range(self):
        """`(predicate, allowed range)` of the release amplitude `a0`, checked by
        [`vmj.turning_points`][]."""
        return positive, f"> 0 [{self.position_unit}]"

    @abc.abstractmethod
    def rest(self, t, x):
        """The stick rule at rest at `(t, x)`: `(s, t_go, stuck)`, the direction of the next
        swing (+-1), the time it starts (`t`, or a later release) and whether the mass stays
        put for good."""

    @abc.abstractmethod
    def swing_scale(self, t, x) -> Array:
        """Amplitude scale of the half-swing that starts from rest at `(t, x)` (sets the
        substeps of nonlinear models)."""

    @abc.abstractmethod
    def taylor(self, t, x, v, s, order: int) -> list:
        """Taylor coefficients `x_0 .. x_order` of the half-swing solution (friction sign `s`)
        about time `t` from the state `(x, v)`."""

    @abc.abstractmethod
    def substep(self, t, scale):
        """`(h, limited, t_next)`: the substep length from `t` (well inside the Taylor series'
        radius of convergence, and shorter than twice the shortest time between two velocity
        zeros: the exact solver tests the velocity's sign at mid-substep and at its end),
        whether it is limited by the approach of the model's lifetime, and where the substep
        ends (`t + h`, or a breakpoint of a piecewise model)."""

    @abc.abstractmethod
    def half_period(self, t, scale) -> Array:
        """Estimated duration of a half-swing starting at `t` [s] (a starting guess only)."""

    def horizon(self, a0, n: int) -> Array:
        """A time by which `n` half-swings are over [s]: 1.3 times the sum of estimated
        half-periods, kept short of the lifetime."""
        life = self.lifetime()

        def body(t, _):
            return t + self.half_period(jnp.minimum(t, 0.999 * life), a0), None

        t, _ = lax.scan(body, jnp.zeros_like(jnp.asarray(a0, dtype=float)), None, length=n + 1)
        return jnp.minimum(1.3 * t, 0.999 * life)


class AbstractEnergyMap(AbstractDecayModel):
    """A decay model with a closed-form half-swing map from an energy balance
    (for [`vmj.EnergyBalance`][])."""

    @abc.abstractmethod
    def energy_map(self, a0, n: int):
        """The first `n` turning points from the energy balance: a [`vmj.DecaySequence`][]."""

    def guard_energy_map(self):
        """Raise `ValueError` when this model's energy map does not apply; return the model,
        guarded with `equinox.error_if` where that depends on traced values."""
        return self


class AbstractAnalytic(AbstractModel):
    """A model with a closed-form response (for [`vmj.ClosedForm`][])."""

    @abc.abstractmethod
    def response(self, t, x0, v0):
        """Displacement and velocity `(x, v)` at times `t` from `x(0) = x0`, `x'(0) = v0`."""


class AbstractLimitCycle(AbstractModel):
    """A self-excited model whose solution settles into a limit cycle
    (for [`vmj.limit_cycle`][])."""

    @abc.abstractmethod
    def exact_cycle(self, max_reversals: int):
        """The cycle from the exact (event-driven) rules."""

    @abc.abstractmethod
    def closed_form_cycle(self, max_reversals: int):
        """The cycle from the source paper's closed forms."""

    @abc.abstractmethod
    def smoothed_cycle(self, max_reversals: int, solver):
        """The cycle measured on the smoothed model (concrete models only)."""

    @abc.abstractmethod
    def breakaway(self):
        """`(x0, v0)`: the state at which the cycle starts."""


def check_horizon(model: AbstractModel, t1, name: str = "t1") -> None:
    """Refuse (`ValueError`) a concrete time `t1` [s] at or beyond the model's lifetime."""
    life = model.lifetime()
    if _is_traced(life) or _is_traced(t1):
        return
    t_max = float(np.max(np.asarray(t1)))
    if t_max >= float(life):
        raise ValueError(
            f"{name} must be below {model.lifetime_text} = {float(life):.6g} s "
            f"(got {t_max:.6g}); the model is meaningless beyond it"
        )


_SCALAR_FIELDS = "_vmj_scalar_fields"  #: set on a concrete model found to have scalar fields


def require_scalar_fields(model) -> bool:
    """Refuse a model with array parameters at an entry point that solves one model; returns
    whether the model is concrete (no traced leaf). (A concrete model that passed is marked and
    not walked again: modules are immutable, and the walk cost a warm single solve 3.6 us.)"""
    module = instance_of(model, AbstractParams)
    if module and own_fields(model).get(_SCALAR_FIELDS, False):
        return True
    concrete = True
    for leaf in jax.tree.leaves(model):
        if _is_traced(leaf):
            concrete = False
        elif getattr(leaf, "shape", ()) != ():  # (jnp.ndim: 3x slower)
            raise ValueError(
                "this entry point takes a model with scalar parameters; for arrays of parameters "
                "use vmj.sweep or jax.vmap"
            )
    if module and concrete:
        object.__setattr__(model, _SCALAR_FIELDS, True)
    return concrete
