"""vmj: oscillators with dry (Coulomb) friction and time-varying parameters, in JAX.

Enable float64 before any computation (the `vmj` command line does it for you):

    import jax
    jax.config.update("jax_enable_x64", True)

The public API, by concern:

- models ([`VariableMass`][vmj.VariableMass], [`Rope`][vmj.Rope], [`Oscillator`][vmj.Oscillator],
  [`LinearOscillator`][vmj.LinearOscillator], [`StickSlip`][vmj.StickSlip]) and the laws they are
  built from (friction, restoring and dissipation laws, length profiles, forcing);
- solvers ([`Exact`][vmj.Exact], [`Smoothed`][vmj.Smoothed], [`EnergyBalance`][vmj.EnergyBalance],
  [`ClosedForm`][vmj.ClosedForm]) passed to one entry point per problem type:
  [`turning_points`][vmj.turning_points] (and the motion between them,
  [`decay_trajectory`][vmj.decay_trajectory]), [`simulate`][vmj.simulate],
  [`limit_cycle`][vmj.limit_cycle];
- results ([`DecaySequence`][vmj.DecaySequence], [`Trajectory`][vmj.Trajectory],
  [`StickSlipCycle`][vmj.StickSlipCycle]) with their status ([`RESULTS`][vmj.RESULTS]);
- closed forms and averaged laws of the source papers;
- sweeps, grids, sensitivities; the paper's tables; figures in `vmj.plot`.

Nothing heavy is imported by `import vmj`: each name below is loaded on first use (JAX, equinox
and diffrax only when a model, solver or entry point is touched), so that the `vmj` command
answers `--help` and argument errors at once.
"""

from typing import TYPE_CHECKING

from ._version import __version__ as __version__

if TYPE_CHECKING:  # the table of contents, read by type checkers and the docs as written
    from ._checks import AbstractParams, assume_valid
    from ._host import one_kernel_loops, retain_host_memory
    from ._integrate import decay_trajectory, limit_cycle, simulate, turning_points
    from ._laws._dissipation import CoulombDamping, DissipationLaw, QuadraticDamping, ViscousDamping
    from ._laws._forcing import BaseMotion, Forcing, HarmonicForce, NoForcing
    from ._laws._friction import AffineFriction, Coulomb, FrictionLaw, MassProportional
    from ._laws._length import Braking, ConstantSpeed, LengthProfile
    from ._laws._restoring import LinearRestoring, PolynomialRestoring, RestoringLaw, SineRestoring
    from ._models._base import (
        AbstractAnalytic,
        AbstractDecayModel,
        AbstractEnergyMap,
        AbstractLimitCycle,
        AbstractModel,
    )
    from ._models._linear import LinearOscillator
    from ._models._oscillator import Oscillator
    from ._models._rope import (
        KGF,
        Rope,
        action_amplitude,
        action_frequency,
        kbm_amplitude,
        kbm_frequency,
    )
    from ._models._stick_slip import StickSlip, StickSlipCycle
    from ._models._variable_mass import VariableMass
    from ._solution import RESULTS, DecaySequence, SolverError, Trajectory
    from ._solvers._base import AbstractSolver
    from ._solvers._closed import ClosedForm, EnergyBalance
    from ._solvers._exact import Exact
    from ._solvers._smoothed import Smoothed
    from ._sweep import (
        Grid,
        SweepError,
        SweepResult,
        grid,
        map_chunks,
        resolve_field,
        sensitivity,
        sweep,
    )
    from ._tables import PAPER, paper_cells, paper_model, paper_table


__all__ = [
    # models and laws
    "AbstractParams",
    "AbstractModel",
    "AbstractDecayModel",
    "AbstractEnergyMap",
    "AbstractAnalytic",
    "AbstractLimitCycle",
    "VariableMass",
    "Rope",
    "Oscillator",
    "LinearOscillator",
    "StickSlip",
    "FrictionLaw",
    "Coulomb",
    "MassProportional",
    "AffineFriction",
    "RestoringLaw",
    "LinearRestoring",
    "PolynomialRestoring",
    "SineRestoring",
    "DissipationLaw",
    "ViscousDamping",
    "CoulombDamping",
    "QuadraticDamping",
    "LengthProfile",
    "ConstantSpeed",
    "Braking",
    "KGF",
    "Forcing",
    "NoForcing",
    "HarmonicForce",
    "BaseMotion",
    "assume_valid",
    # solvers and entry points
    "AbstractSolver",
    "Exact",
    "Smoothed",
    "EnergyBalance",
    "ClosedForm",
    "turning_points",
    "decay_trajectory",
    "simulate",
    "limit_cycle",
    # results
    "RESULTS",
    "SolverError",
    "DecaySequence",
    "Trajectory",
    "StickSlipCycle",
    # closed forms and averaged laws
    "kbm_amplitude",
    "kbm_frequency",
    "action_amplitude",
    "action_frequency",
    # sweeps and sensitivities
    "Grid",
    "SweepResult",
    "SweepError",
    "grid",
    "sweep",
    "sensitivity",
    "map_chunks",
    "resolve_field",
    "retain_host_memory",
    "one_kernel_loops",
    # the variable-mass paper's tables
    "PAPER",
    "paper_cells",
    "paper_model",
    "paper_table",
]


def _table() -> dict:
    """Public name -> module, read once from the `if TYPE_CHECKING:` block above (the one list)."""
    import ast
    import pathlib

    tree = ast.parse(pathlib.Path(__file__).read_text(encoding="utf-8"))
    block = next(
        n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING"
    )
    return {
        alias.name: "." * node.level + node.module
        for node in block.body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    }


_LAZY: dict | None = None


def __getattr__(name: str):
    """Load a public name (or a submodule such as `vmj.plot`) on first use."""
    import importlib

    global _LAZY
    if _LAZY is None:
        _LAZY = _table()
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value  # later lookups skip this function
        return value
    if not name.startswith("__"):
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as e:
            if e.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(__all__))
