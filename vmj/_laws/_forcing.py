"""Excitations of the linear oscillator: none, a harmonic force, a harmonic base motion."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array

from .._checks import AbstractParams, _float, anything, positive

__all__ = ["Forcing", "NoForcing", "HarmonicForce", "BaseMotion"]


class Forcing(AbstractParams):
    """Excitation of a [`vmj.LinearOscillator`][]."""

    @abc.abstractmethod
    def force(self, osc, t) -> Array:
        """External force on the mass [N] at time `t` [s]."""

    @abc.abstractmethod
    def complex_amplitude(self, osc):
        """`(Q, p)`: the force is `Im(Q exp(i p t))` [N] with angular frequency `p` [1/s]."""


class NoForcing(Forcing):
    """No excitation (free vibration)."""

    def force(self, osc, t):
        return jnp.zeros_like(jnp.asarray(t, dtype=osc.m.dtype))

    def complex_amplitude(self, osc):
        return jnp.zeros_like(osc.m) + 0j, jnp.zeros_like(osc.m)


class HarmonicForce(Forcing):
    """Harmonic force `F0 sin(p t)`.

    **Arguments:** `F0` force amplitude [N] (any real number); `p` angular frequency [1/s], `> 0`.
    """

    F0: Array = eqx.field(converter=_float)
    p: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {"F0": (anything, "a real number [N]"), "p": (positive, "> 0 [1/s]")}

    def force(self, osc, t):
        return self.F0 * jnp.sin(self.p * t)

    def complex_amplitude(self, osc):
        return self.F0 + 0j, self.p


class BaseMotion(Forcing):
    """Harmonic motion of the base `y(t) = Y0 sin(p t)` through the spring and the damper:
    the force on the mass is `k y + c y'`, and `x` is the absolute displacement.

    **Arguments:** `Y0` base amplitude [m] (any real number); `p` angular frequency [1/s], `> 0`.
    """

    Y0: Array = eqx.field(converter=_float)
    p: Array = eqx.field(converter=_float)
    _limits: ClassVar[dict] = {"Y0": (anything, "a real number [m]"), "p": (positive, "> 0 [1/s]")}

    def force(self, osc, t):
        return self.Y0 * (osc.k * jnp.sin(self.p * t) + osc.c * self.p * jnp.cos(self.p * t))

    def complex_amplitude(self, osc):
        return self.Y0 * (osc.k + 1j * osc.c * self.p), self.p
