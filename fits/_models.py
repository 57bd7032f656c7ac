"""The model families of the fits, by name (`SPACES`): the variable-mass oscillator, the
normalised constant-mass oscillator, the rope of varying length and the pendulum
(`fits._pendulum`). What a family is: `fits._space.Space`.

The constant-mass oscillator's `"exact"` method is `vmj.EnergyBalance()` of
`vmj.Oscillator.linear`, its exact closed-form half-swing map (what the decrement method
linearises).
"""

from __future__ import annotations

import vmj

from ._pendulum import PENDULUM
from ._record import Record
from ._space import SOLVERS, Space, first_amplitude, friction_variants, record_centre

__all__ = ["SPACES"]


def _omega_without_times(record: Record):
    """The oscillator's `omega` only sets the time scale: for a record without times the
    turning points do not depend on it (1 rad/s, nominal); a record with times must give or
    fit it (no default)."""
    return 1.0 if record.times is None else None


# -- variable-mass oscillator ------------------------------------------------------------------
def _variable_mass(theta: dict):
    law = vmj.AffineFriction(theta["FT"], theta["f"], theta["g"])
    model = vmj.VariableMass(
        theta["m0"], theta["c"], theta["delta"], theta["eps"], theta["mu"], law
    )
    return model, theta["a0"], 1.0


VARIABLE_MASS = Space(
    name="variable-mass",
    names=("FT", "f", "mu", "eps", "delta", "a0", "offset", "m0", "c", "g"),
    kinds=(
        "positive",
        "positive",
        "positive",
        "unit",
        "real",
        "positive",
        "real",
        "positive",
        "positive",
        "positive",
    ),
    units=("N", "-", "kg/s", "-", "kg/s", "m", "m", "kg", "N/m", "m/s^2"),
    dry=("FT", "f"),
    viscous=("mu",),
    required=("m0", "c"),
    model=_variable_mass,
    defaults={
        "FT": 0.0,
        "f": 0.0,
        "mu": 0.0,
        "eps": 0.0,
        "delta": 0.0,
        "g": 9.81,
        "a0": first_amplitude,
        "offset": record_centre,
    },
    variants=friction_variants(("FT", "f"), ("mu",)),
)


# -- normalised constant-mass oscillator -------------------------------------------------------
def _oscillator(theta: dict):
    """`vmj.Oscillator.linear`: its energy balance is the exact closed-form half-swing map, so
    the "exact" forward model uses it (the same numbers as `vmj.Exact()`, cheaper)."""
    return vmj.Oscillator.linear(theta["omega"], theta["zeta"], theta["xF"]), theta["a0"], 1.0


OSCILLATOR = Space(
    name="oscillator",
    names=("omega", "zeta", "xF", "a0", "offset", "asym", "drift"),
    kinds=("positive", "damping", "positive", "positive", "real", "real", "real"),
    units=("rad/s", "-", "signal", "signal", "signal", "-", "signal/s"),
    dry=("xF",),
    viscous=("zeta",),
    required=("omega",),
    model=_oscillator,
    solvers={**SOLVERS, "exact": vmj.EnergyBalance},
    defaults={
        "zeta": 0.0,
        "xF": 0.0,
        "asym": 0.0,
        "drift": 0.0,
        "a0": first_amplitude,
        "offset": record_centre,
        "omega": _omega_without_times,
    },
    variants=friction_variants(("xF",), ("zeta",)),
    bounds={"asym": (-0.5, 0.5)},
    constant_laws=True,
)


# -- mass on a rope of varying length (Osinski) ------------------------------------------------
def _rope(theta: dict):
    rope = vmj.Rope(
        theta["m"],
        theta["A"],
        theta["e"],
        theta["b"],
        theta["d"],
        theta["T"],
        vmj.ConstantSpeed(theta["l0"], theta["u"]),
    )
    return rope, theta["a0"], 1.0


ROPE = Space(
    name="rope",
    names=("T", "e", "d", "b", "a0", "offset", "m", "A", "l0", "u"),
    kinds=(
        "positive",
        "positive",
        "positive",
        "real",
        "positive",
        "real",
        "positive",
        "positive",
        "positive",
        "real",
    ),
    units=("Pa", "Pa", "Pa", "Pa", "m", "m", "kg", "m^2", "m", "m/s"),
    dry=("T",),
    viscous=(),
    required=("m", "A", "e", "l0"),
    model=_rope,
    defaults={
        "T": 0.0,
        "d": 0.0,
        "b": 0.0,
        "u": 0.0,
        "a0": first_amplitude,
        "offset": record_centre,
    },
)

SPACES = {s.name: s for s in (VARIABLE_MASS, OSCILLATOR, ROPE, PENDULUM)}
