"""Forward models of the fits: turning-point sequences as functions of a parameter vector.

Each model family is a `Space`: its parameter names, how each is kept in range during the fit
(`kinds`), which parameters are dry and which viscous friction (for the model comparison), and
`predict(theta, n, forward)` returning the release point and the first `n` turning points
`(times [s], signed positions)` of the model released from rest at `-a0`. The constant offset
and the orientation of the record are applied by the fit, not here.

Every `predict` wraps `vmj.turning_points` (one solver per method); the constant-mass
oscillator's `"exact"` method is `vmj.EnergyBalance()` of `vmj.Oscillator.linear`, its exact
closed-form half-swing map (what the decrement method linearises).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import jax.numpy as jnp

import vmj

__all__ = ["Space", "SPACES", "FORWARDS"]

FORWARDS = ("exact", "smooth", "energy")

#: how a parameter is kept in range: theta = scale p (real), scale p^2 (positive),
#: sin(p)^2 (unit: [0, 1])
KIND_CODES = {"real": 0, "positive": 1, "unit": 2, "damping": 2}  # damping: [0, 1)


@dataclass(frozen=True)
class Space:
    """A model family for fitting (static; compared by name)."""

    name: str
    names: tuple
    kinds: tuple
    units: tuple
    dry: tuple  #: dry-friction parameters (fixed to 0 for the viscous-only comparison)
    viscous: tuple  #: viscous parameters (fixed to 0 for the Coulomb-only comparison)
    required: tuple  #: parameters that must be given when not fitted
    predict: Callable = None

    def index(self, name: str) -> int:
        return self.names.index(name)

    def __hash__(self):
        return hash(self.name)

    def __eq__(self, other):
        return isinstance(other, Space) and other.name == self.name


def _sequence(seq, a0):
    times = jnp.concatenate([jnp.zeros((1,)), seq.times])
    positions = jnp.concatenate([-jnp.reshape(a0, (1,)), seq.positions])
    return times, positions


# -- variable-mass oscillator ------------------------------------------------------------------
def _variable_mass(theta: dict, n: int, forward: str):
    law = vmj.AffineFriction(theta["FT"], theta["f"], theta["g"])
    model = vmj.VariableMass(theta["m0"], theta["c"], theta["delta"], theta["eps"], theta["mu"],
                             law)
    return _sequence(vmj.turning_points(model, theta["a0"], n, method=forward), theta["a0"])


VARIABLE_MASS = Space(
    name="variable-mass",
    names=("FT", "f", "mu", "eps", "delta", "a0", "offset", "m0", "c", "g"),
    kinds=("positive", "positive", "positive", "unit", "real", "positive", "real", "positive",
           "positive", "positive"),
    units=("N", "-", "kg/s", "-", "kg/s", "m", "m", "kg", "N/m", "m/s^2"),
    dry=("FT", "f"),
    viscous=("mu",),
    required=("m0", "c"),
    predict=_variable_mass,
)


# -- normalised constant-mass oscillator -------------------------------------------------------
_OSCILLATOR_SOLVERS = {"exact": vmj.EnergyBalance, "smooth": vmj.Smoothed,
                       "energy": vmj.EnergyBalance}


def _oscillator(theta: dict, n: int, forward: str):
    """`vmj.Oscillator.linear`: its energy balance is the exact closed-form half-swing map, so
    the "exact" forward model uses it (the same numbers as `vmj.Exact()`, cheaper)."""
    model = vmj.Oscillator.linear(theta["omega"], theta["zeta"], theta["xF"])
    seq = vmj.turning_points(model, theta["a0"], n, _OSCILLATOR_SOLVERS[forward]())
    return _sequence(seq, theta["a0"])


OSCILLATOR = Space(
    name="oscillator",
    names=("omega", "zeta", "xF", "a0", "offset"),
    kinds=("positive", "damping", "positive", "positive", "real"),
    units=("rad/s", "-", "signal", "signal", "signal"),
    dry=("xF",),
    viscous=("zeta",),
    required=(),
    predict=_oscillator,
)

# -- mass on a rope of varying length (Osinski) ------------------------------------------------
def _rope(theta: dict, n: int, forward: str):
    rope = vmj.Rope(theta["m"], theta["A"], theta["e"], theta["b"], theta["d"], theta["T"],
                    vmj.ConstantSpeed(theta["l0"], theta["u"]))
    return _sequence(vmj.turning_points(rope, theta["a0"], n, method=forward), theta["a0"])


ROPE = Space(
    name="rope",
    names=("T", "e", "d", "b", "a0", "offset", "m", "A", "l0", "u"),
    kinds=("positive", "positive", "positive", "real", "positive", "real", "positive",
           "positive", "positive", "real"),
    units=("Pa", "Pa", "Pa", "Pa", "m", "m", "kg", "m^2", "m", "m/s"),
    dry=("T",),
    viscous=(),
    required=("m", "A", "e", "l0"),
    predict=_rope,
)

SPACES = {s.name: s for s in (VARIABLE_MASS, OSCILLATOR, ROPE)}


def theta_dict(space: Space, theta) -> dict:
    return {name: theta[..., i] for i, name in enumerate(space.names)}
