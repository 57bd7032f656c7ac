"""The one table that builds vmj models from flat command-line parameters.

For each model name of the command line it lists the parameters with their spelling on the command
line, unit, default and the model field they set, and a builder from flat values to the vmj model.
`vmj decay`, `vmj sweep` and `vmj sensitivity` read it, so a parameter is spelled, documented and
checked the same way in every command.

The allowed range of a model parameter is the model's own (`_limits` of the class that owns the
field); the command line only states it with its own spelling (`--FT`, not `F`). Building a model
imports vmj's solvers; reading this table does not.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Param", "Above", "ModelSpec", "MODELS", "add_options", "given"]


@dataclass(frozen=True)
class Param:
    """One command-line parameter.

    - `name`: its spelling on the command line (`--NAME`, `--set NAME=...`, `--wrt NAME`).
    - `help`: what it is, with its unit in brackets.
    - `owner`, `field`: the vmj class (a public name) whose `_limits` give the allowed range,
      and the dotted path of the field in the built model (`None`: not a model field, e.g. the
      initial deflection).
    - `allowed`: `(predicate, text)` for parameters no vmj class checks (initial conditions).
    - `default`: `None` if it must be given (unless its `group` is given another way).
    - `group`: a set of alternatives; `requires`: a parameter that must be given with it.
    - `aliases`: other accepted spellings (the model's field name).
    - `technical`: the rope paper's technical unit: `(factor(vmj), unit)`, the factor to SI
      read from vmj (`vmj.KGF`) when a value is checked.
    """

    name: str
    help: str
    owner: str | None = None
    field: str | None = None
    allowed: tuple | None = None
    default: float | None = None
    group: str | None = None
    requires: str | None = None
    aliases: tuple = ()
    technical: tuple | None = None

    def limits(self) -> tuple[Callable, str]:
        """`(predicate, allowed range)` of this parameter."""
        if self.allowed is not None:
            return self.allowed
        import vmj

        return getattr(vmj, self.owner)._limits[self.field.rsplit(".", 1)[-1]]

    def check(self, value: float, flag: str, technical: bool = False) -> float:
        """`value` in SI after checking it against the allowed range; `ValueError` naming
        `flag` (the spelling the user gave) otherwise."""
        factor, unit = (1.0, None)
        if technical and self.technical:
            import vmj

            factor, unit = self.technical[0](vmj), self.technical[1]
        si = value * factor
        ok, allowed = self.limits()
        if not (math.isfinite(si) and bool(ok(si))):
            got = f"{value:g} {unit}" if unit else f"{value:g}"
            raise ValueError(f"{flag} must be finite and {allowed} (got {got})")
        return si


_POSITIVE_LENGTH = (lambda x: x > 0, "> 0 [m]")


@dataclass(frozen=True)
class Above:
    """A range across two parameters: `name` must be above `other` (its unit in `unit`) at
    every point, as the model's `_relations` demand (stated here with the user's spelling)."""

    name: str
    other: str
    unit: str

    def check(self, values: dict) -> None:
        """`values`: `{name: (SI values, flag)}`, several values for a sweep's axis; every
        combination must hold."""
        if self.name in values and self.other in values:
            (high, flag), (low, other_flag) = values[self.name], values[self.other]
            if not min(high) > max(low):
                raise ValueError(
                    f"{flag} must be > {other_flag} {self.unit} (got {min(high):g} <= {max(low):g})"
                )


@dataclass(frozen=True)
class ModelSpec:
    """A model of the command line: its parameters (model fields first, then the initial
    conditions; a sweep's axes follow this order, as `vmj.grid`'s), `build(values)` from
    `{name: SI value}` to the vmj model, and the ranges across parameters (`Above`)."""

    name: str
    params: tuple
    build: Callable
    summary: str
    relations: tuple = ()

    def param(self, name: str) -> Param:
        """The parameter spelled `name` (or one of its aliases); `ValueError` listing the known
        names otherwise."""
        for p in self.params:
            if name == p.name or name in p.aliases:
                return p
        raise ValueError(
            f"unknown parameter {name!r} of {self.name} (known: "
            f"{', '.join(p.name for p in self.params)})"
        )

    @property
    def fields(self) -> tuple:
        return tuple(p for p in self.params if p.field is not None)

    def resolve(
        self, values: dict, technical: bool = False, spell=lambda n: f"--{n}", axes=None
    ) -> dict:
        """Check `{name: (value, flag)}` (the flag as spelled by the user) parameter by
        parameter and across parameters (missing, alternatives, requirements, `relations`);
        fill in the defaults. `spell(name)` says how a missing parameter is given; `axes`
        (a sweep's `{name: SI values}`, each checked) replaces a parameter's single value in
        the relations. Returns `{name: SI value}`."""
        out = {
            name: self.param(name).check(value, flag, technical)
            for name, (value, flag) in values.items()
        }
        axes = axes or {}
        spread = {name: (axes.get(name, [out[name]]), flag) for name, (_, flag) in values.items()}
        for relation in self.relations:
            relation.check(spread)
        missing, groups = [], {}
        for p in self.params:
            if p.group is not None:
                groups.setdefault(p.group, []).append(p)
            elif p.requires is not None:
                if p.name in out and p.requires not in out:
                    raise ValueError(f"{values[p.name][1]} goes with {spell(p.requires)}")
            elif p.name not in out:
                if p.default is None:
                    missing.append(f"{spell(p.name)} ({p.help})")
                out[p.name] = p.default
        for members in groups.values():
            named = [p.name for p in members if p.name in out]
            choices = " or ".join(f"{spell(p.name)} ({p.help})" for p in members)
            if len(named) > 1:
                raise ValueError(f"give only one of {choices}")
            if not named:
                missing.append(f"one of {choices}")
        if missing:
            raise ValueError(f"missing {'; '.join(missing)}")
        for p in self.params:  # parameters with a requirement take their default with it
            if p.requires in out and p.name not in out and p.default is not None:
                out[p.name] = p.default
        return out


# -- variable-mass -------------------------------------------------------------------------------
def _variable_mass(v: dict):
    import vmj

    law = vmj.Coulomb(v["FT"]) if "FT" in v else vmj.MassProportional(v["f"], v["g"])
    return vmj.VariableMass(v["m0"], v["c"], v["delta"], v["eps"], v["mu"], law)


VARIABLE_MASS = ModelSpec(
    "variable-mass",
    (
        Param("eps", "reactivity coefficient [-]", "VariableMass", "eps"),
        Param("mu", "viscous friction coefficient [kg/s]", "VariableMass", "mu"),
        Param("delta", "rate of change of the mass [kg/s]", "VariableMass", "delta"),
        Param("m0", "initial mass [kg]", "VariableMass", "m0"),
        Param("c", "spring stiffness [N/m]", "VariableMass", "c"),
        Param(
            "FT",
            "constant dry friction force [N]",
            "Coulomb",
            "friction.F",
            group="friction",
            aliases=("F",),
        ),
        Param(
            "f",
            "dry friction coefficient, F = f g m(t) [-]",
            "MassProportional",
            "friction.f",
            group="friction",
        ),
        Param(
            "g",
            "gravity, with --f [m/s^2]",
            "MassProportional",
            "friction.g",
            default=9.81,
            requires="f",
        ),
        Param("a0", "initial deflection [m]", allowed=_POSITIVE_LENGTH),
    ),
    _variable_mass,
    "linearly varying mass with reactive force, viscous and dry friction (Olshansky)",
)


# -- rope ----------------------------------------------------------------------------------------
def _rope(v: dict):
    import vmj

    if "t_brake" in v:
        length = vmj.Braking(v["l0"], v["u"], v["t_brake"], v["t_stop"])
    else:
        length = vmj.ConstantSpeed(v["l0"], v["u"])
    return vmj.Rope(v["m"], v["A"], v["e"], v["b"], v["d"], v["T"], length)


_STRESS = (lambda vmj: vmj.KGF * 1e4, "kG/cm^2")  # as vmj.Rope.from_technical converts
ROPE = ModelSpec(
    "rope",
    (
        Param(
            "m",
            "suspended mass [kg] (technical: kG s^2/m)",
            "Rope",
            "m",
            technical=(lambda vmj: vmj.KGF, "kG s^2/m"),
        ),
        Param(
            "A",
            "rope cross-section [m^2] (technical: cm^2)",
            "Rope",
            "A",
            technical=(lambda vmj: 1e-4, "cm^2"),
        ),
        Param("e", "linear modulus [Pa] (technical: kG/cm^2)", "Rope", "e", technical=_STRESS),
        Param(
            "b",
            "quadratic coefficient [Pa] (technical: kG/cm^2)",
            "Rope",
            "b",
            default=0.0,
            technical=_STRESS,
        ),
        Param(
            "d",
            "cubic coefficient [Pa] (technical: kG/cm^2)",
            "Rope",
            "d",
            default=0.0,
            technical=_STRESS,
        ),
        Param(
            "T",
            "friction stress between the wires [Pa] (technical: kG/cm^2)",
            "Rope",
            "T",
            technical=_STRESS,
        ),
        Param("l0", "initial free rope length [m]", "ConstantSpeed", "length.l0"),
        Param(
            "u", "hoisting speed [m/s] (> 0 hoisting, < 0 lowering)", "ConstantSpeed", "length.u"
        ),
        Param(
            "t_brake",
            "time the drum starts braking [s], with --t_stop",
            "Braking",
            "length.t_brake",
            requires="t_stop",
        ),
        Param(
            "t_stop",
            "time the drum stops [s], with --t_brake",
            "Braking",
            "length.t_stop",
            requires="t_brake",
        ),
        Param(
            "a0",
            "initial deflection [m] (technical: cm)",
            allowed=_POSITIVE_LENGTH,
            technical=(lambda vmj: 1e-2, "cm"),
        ),
    ),
    _rope,
    "mass on a hoisting rope of varying length with friction between the wires (Osinski)",
    (Above("t_stop", "t_brake", "[s]"),),
)


# -- stick-slip ----------------------------------------------------------------------------------
def _stick_slip(v: dict):
    import vmj

    return vmj.StickSlip(v["eps"], v["Omega"])


STICK_SLIP = ModelSpec(
    "stick-slip",
    (
        Param("eps", "static/sliding friction ratio M1/M0 [-]", "StickSlip", "eps"),
        Param("Omega", "dimensionless drive speed omega sqrt(c I)/M0 [-]", "StickSlip", "Omega"),
    ),
    _stick_slip,
    "stick-slip limit cycle with instantaneous velocity reversal (Belokobylsky)",
)


# -- linear --------------------------------------------------------------------------------------
def _linear(v: dict):
    import vmj

    forcing = vmj.HarmonicForce(v["F0"], v["p"]) if "F0" in v else vmj.NoForcing()
    return vmj.LinearOscillator(v["m"], v["c"], v["k"], forcing)


LINEAR = ModelSpec(
    "linear",
    (
        Param("m", "mass [kg]", "LinearOscillator", "m"),
        Param("c", "viscous damping [N s/m]", "LinearOscillator", "c"),
        Param("k", "stiffness [N/m]", "LinearOscillator", "k"),
        Param(
            "F0",
            "harmonic force amplitude [N], with --p",
            "HarmonicForce",
            "forcing.F0",
            requires="p",
        ),
        Param(
            "p",
            "forcing angular frequency [1/s], with --F0",
            "HarmonicForce",
            "forcing.p",
            requires="F0",
        ),
        Param(
            "x0",
            "initial displacement [m]",
            allowed=(lambda x: x == x, "a real number [m]"),
            default=0.0,
        ),
        Param(
            "v0",
            "initial velocity [m/s]",
            allowed=(lambda x: x == x, "a real number [m/s]"),
            default=0.0,
        ),
    ),
    _linear,
    "linear one-degree-of-freedom oscillator, free or harmonically forced",
)

#: the models of the command line, by name
MODELS = {spec.name: spec for spec in (VARIABLE_MASS, ROPE, STICK_SLIP, LINEAR)}


def add_options(parser, spec: ModelSpec, axes: bool = False) -> None:
    """One option `--NAME` per parameter of `spec`: a number (`axes=False`; required ones are
    required, alternatives mutually exclusive) or an axis string (`axes=True`, all optional:
    `--set` may give them instead)."""
    from ._options import number

    groups = {}
    for p in spec.params:
        text = p.help
        if p.default is not None:
            text += f" (default: {p.default:g})"
        if axes:
            if p.field is None:  # initial conditions are not swept: --set gives them
                continue
            parser.add_argument(f"--{p.name}", metavar="AXIS", help=text)
            continue
        target = parser
        if p.group is not None:
            if p.group not in groups:
                groups[p.group] = parser.add_mutually_exclusive_group(required=True)
            target = groups[p.group]
        required = p.default is None and p.group is None and p.requires is None
        target.add_argument(f"--{p.name}", type=number, required=required, help=text)


def given(spec: ModelSpec, args) -> dict:
    """`{name: (value, flag)}` for the parameters of `spec` given as options in `args`."""
    return {
        p.name: (getattr(args, p.name), f"--{p.name}")
        for p in spec.params
        if getattr(args, p.name, None) is not None
    }
