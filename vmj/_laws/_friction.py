"""Dry (Coulomb) friction laws of the variable-mass oscillator: the friction force as an affine
function of the current mass."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._checks import AbstractParams, _float, nonnegative, positive

__all__ = ["FrictionLaw", "Coulomb", "MassProportional", "AffineFriction"]


class FrictionLaw(AbstractParams):
    """Dry friction law: the force magnitude [N] as an affine function of the mass [kg]."""

    #: whether the force can change with the mass (a class constant, known when tracing)
    varies_with_mass: ClassVar[bool] = True

    @abc.abstractmethod
    def force(self, mass: ArrayLike) -> Array:
        """Friction force magnitude [N] when the oscillating mass is `mass` [kg]."""

    @abc.abstractmethod
    def dforce_dmass(self) -> Array:
        """Derivative of the friction force with respect to the mass [N/kg]."""


class Coulomb(FrictionLaw):
    """Constant dry friction force.

    **Arguments:**

    - `F`: friction force magnitude `F_T` [N], `>= 0` (the command line's `--FT`).
    """

    varies_with_mass: ClassVar[bool] = False

    F: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {"F": (nonnegative, ">= 0 [N]")}

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
    _limits: ClassVar[dict] = {"f": (nonnegative, ">= 0 [-]"), "g": (positive, "> 0 [m/s^2]")}

    def force(self, mass):
        return self.f * self.g * mass

    def dforce_dmass(self):
        return self.f * self.g


class AffineFriction(FrictionLaw):
    """Dry friction `F(t) = F_T + f g m(t)`: covers [`vmj.Coulomb`][] (`f = 0`) and
    [`vmj.MassProportional`][] (`F_T = 0`) with one compiled model, so that fits of both laws
    (and their comparison) share one compilation.

    **Arguments:** `FT` [N] `>= 0`, `f` [-] `>= 0`, `g` [m/s^2] `> 0`.
    """

    FT: Array = eqx.field(converter=_float)
    f: Array = eqx.field(converter=_float)
    g: Array = eqx.field(converter=_float, default=9.81)
    _limits: ClassVar[dict] = {
        "FT": (nonnegative, ">= 0 [N]"),
        "f": (nonnegative, ">= 0 [-]"),
        "g": (positive, "> 0 [m/s^2]"),
    }

    def force(self, mass):
        return self.FT + self.f * self.g * mass

    def dforce_dmass(self):
        return self.f * self.g
